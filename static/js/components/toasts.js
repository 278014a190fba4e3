/* Toasts: at most MAX_SHOWN shown, newest first; the rest wait behind "+N more" (with
   "dismiss all"). A toast with a key (an alarm: its camera and event) is updated in
   place by the next one with the same key rather than stacked again. A click on a toast,
   its close button (Tab reaches it) or Escape (the newest) closes it; an alarm's toast
   closed so stays closed while its event goes on (it alarms again every second or so, and
   the user closed it to reach what it covered): the alarm list still counts the alarms. */
import { $, $$ } from "../lib/dom.js";

const MAX_SHOWN = 3;
const MAX_CLOSED = 500;  // Alarm toasts closed by the user, remembered until their event ends.
const CLOSE_BUTTON = '<button type="button" class="toast-close" aria-label="close this message"'
  + ' title="close (Esc closes the newest)">✕</button>';

export class Toasts {
  constructor(box, more) {
    this.box = box;
    this.more = more;
    this.toasts = new Map();  // key -> {key, kind, element, timer, repeats}
    this.closed = new Set();  // keys of the alarm toasts the user closed, oldest first
    $("#toasts-dismiss", more).addEventListener("click", () => {
      for (const toast of this.inOrder()) this.close(toast);
    });
    document.addEventListener("keydown", (event) => {
      // Not an Escape that something else took (a form on a card closes with it).
      if (event.key !== "Escape" || event.defaultPrevented) return;
      const focused = document.activeElement?.closest(".toast");
      const chosen = (focused && this.inOrder().find((t) => t.element === focused)) || this.inOrder()[0];
      if (chosen) this.close(chosen);
    });
  }

  /* Shows a toast (kind: alarm, error or info), unless the user closed it (see above). */
  show(html, kind = "alarm", key = null) {
    key = key || `${kind}:${html}`;
    if (this.closed.has(key)) return;
    let toast = this.toasts.get(key);
    if (toast) {
      clearTimeout(toast.timer);
      toast.repeats += 1;
    } else {
      const element = document.createElement("div");
      element.className = `toast toast-${kind}`;
      element.setAttribute("role", kind === "error" ? "alert" : "status");
      toast = { key, kind, element, timer: null, repeats: 1 };
      element.addEventListener("click", () => this.close(toast));
      this.toasts.set(key, toast);
    }
    const { element } = toast;
    const focused = element.contains(document.activeElement);  // Its close button, kept focused.
    element.innerHTML = html + (toast.repeats > 1 && kind !== "alarm" ? ` <span class="repeats">×${toast.repeats}</span>` : "")
      + CLOSE_BUTTON;
    if (focused) $(".toast-close", element).focus();
    this.box.prepend(element);
    toast.timer = setTimeout(() => this.remove(toast), kind === "error" ? 12000 : 8000);
    this.layout();
  }

  /* The alarm's event has ended: its toast says so, and none of its alarms comes again. */
  ended(key) {
    this.toasts.get(key)?.element.classList.add("ended");
    this.closed.delete(key);
  }

  /* Pictures deleted on the server: the toasts lose them (their words say enough). */
  dropPictures(urls) {
    for (const img of $$("img", this.box)) if (urls.has(img.getAttribute("src"))) img.remove();
  }

  /* The toasts shown and waiting, newest first. */
  inOrder() {
    const byElement = new Map(Array.from(this.toasts.values(), (toast) => [toast.element, toast]));
    return $$(":scope > .toast", this.box).map((element) => byElement.get(element));
  }

  /* Closed by the user (not timed out): an alarm's stays closed until its event ends. */
  close(toast) {
    if (toast.kind === "alarm") {
      this.closed.add(toast.key);
      // Bounded: an event whose end never comes (a server restart) is not kept for ever.
      if (this.closed.size > MAX_CLOSED) this.closed.delete(this.closed.values().next().value);
    }
    this.remove(toast);
  }

  remove(toast) {
    const hadFocus = toast.element.contains(document.activeElement);
    clearTimeout(toast.timer);
    toast.element.remove();
    this.toasts.delete(toast.key);
    this.layout();
    // Closed from the keyboard: on to the next toast's close button, if any.
    if (hadFocus) $(":scope > .toast:not([hidden]) .toast-close", this.box)?.focus();
  }

  layout() {
    const elements = $$(":scope > .toast", this.box);
    elements.forEach((element, i) => { element.hidden = i >= MAX_SHOWN; });
    const waiting = elements.length - MAX_SHOWN;
    this.more.hidden = waiting <= 0;
    $(".count", this.more).textContent = waiting > 0 ? `+${waiting} more` : "";
  }
}
