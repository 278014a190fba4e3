/* The Notifications section: where alarms are sent (Apprise URLs, shown with their secrets
   masked by the server), the form that adds one for every camera or some, and each
   target's state: messages sent and failed, its last error and when, a test message. */
import { api } from "../api/client.js";
import { $, $$, escapeHtml } from "../lib/dom.js";
import { formatDate, plural } from "../lib/format.js";

const TARGETS = "/api/notifications";
const REFRESH_MS = 10000;     // Counts and errors change as alarms are sent.
const AFTER_ALARM_MS = 2500;  // An alarm's message has usually gone by then.

export class Notifications {
  /* cameras: the page's Cameras (names, and the choice of cameras on the form). */
  constructor(section, cameras) {
    this.section = section;
    this.cameras = cameras;
    this.list = $("#targets", section);
    this.form = $("#add-target", section);
    this.choice = $(".target-cameras", this.form);
    this.targets = [];
    this.tests = new Map();   // id -> {ok, text}: the last test's outcome, kept across redraws
    this.timer = null;
    this.form.addEventListener("submit", (event) => this.add(event));
    this.choice.addEventListener("toggle", () => this.renderChoice());
    this.choice.addEventListener("change", () => this.sayChoice());
    this.list.addEventListener("click", (event) => this.onClick(event));
    setInterval(() => { if (!document.hidden) this.load(); }, REFRESH_MS);
  }

  async load() {
    try {
      this.targets = await api("GET", TARGETS);
      this.render();
    } catch (error) {
      $(".targets-error", this.section).textContent = `Cannot list the targets: ${error.message}`;
    }
  }

  /* An alarm has come: its messages are on their way; show how they went. */
  soon() {
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.load(), AFTER_ALARM_MS);
  }

  /* The cameras were listed again: names on the targets, choices on the form. */
  camerasChanged() {
    this.render();
    if (this.choice.open) this.renderChoice();
  }

  render() {
    $(".targets-error", this.section).textContent = "";
    $(".targets-none", this.section).hidden = this.targets.length > 0;
    const known = new Set(this.targets.map((t) => t.id));
    for (const id of this.tests.keys()) if (!known.has(id)) this.tests.delete(id);
    this.list.innerHTML = this.targets.map((t) => this.targetHtml(t)).join("");
  }

  targetHtml(target) {
    const state = target.failing ? ["failing", "failed"] : target.sent ? ["working", "live"]
      : ["no message yet", "queued"];
    const scope = target.cameras === null ? "all cameras"
      : target.cameras.map((id) => this.cameras.name(id)).join(", ");
    const counts = [`${target.sent} sent`, `${target.failed} failed`];
    if (target.pending) counts.push(`${target.pending} waiting`);
    const error = target.last_error
      ? `<p class="target-error${target.failing ? "" : " muted"}">Last error, ${
        escapeHtml(formatDate(target.last_error_at))}: ${escapeHtml(target.last_error)}</p>` : "";
    const test = this.tests.get(target.id);
    const fixed = target.origin === "env";
    return `<li class="target" data-id="${target.id}">
      <div class="target-head">
        <span class="badge state badge-${state[1]}">${state[0]}</span>
        <b class="service">${escapeHtml(target.service)}</b>
        <code class="url">${escapeHtml(target.url)}</code>
      </div>
      <div class="target-facts muted">
        <span class="scope">${escapeHtml(scope)}</span>
        <span class="counts">${counts.join(" · ")}</span>
        ${target.last_sent_at ? `<span>last sent ${escapeHtml(formatDate(target.last_sent_at))}</span>` : ""}
        ${fixed ? '<span class="origin">set by VIGIL_NOTIFY_URLS</span>' : ""}
      </div>
      ${error}
      <div class="target-actions">
        <button type="button" class="test">Send a test</button>
        <span class="test-result ${test ? (test.ok ? "ok" : "error") : ""}" role="status">${
          test ? escapeHtml(test.text) : ""}</span>
        ${fixed ? "" : '<button type="button" class="delete danger" title="remove this target">Remove</button>'}
      </div>
    </li>`;
  }

  /* The form's cameras: a box per camera, as many ticked as before; none ticked: all. */
  renderChoice() {
    const ticked = new Set(this.chosen() || []);
    const boxes = Array.from(this.cameras.values()).map((camera) => `<label>
      <input type="checkbox" value="${camera.id}"${ticked.has(camera.id) ? " checked" : ""}>
      ${escapeHtml(camera.name)}</label>`);
    $(".choices", this.choice).innerHTML = boxes.join("")
      || '<span class="muted">no camera yet</span>';
    this.sayChoice();
  }

  chosen() {
    const ids = $$("input:checked", this.choice).map((box) => Number(box.value));
    return ids.length ? ids : null;
  }

  sayChoice() {
    const ids = this.chosen();
    $("summary", this.choice).textContent = ids ? plural(ids.length, "camera") : "all cameras";
  }

  async add(event) {
    event.preventDefault();
    const error = $(".form-error", this.form);
    error.textContent = "";
    const button = $("button[type=submit]", this.form);
    button.disabled = true;
    try {
      await api("POST", TARGETS, { url: this.form.url.value.trim(), cameras: this.chosen() });
      this.form.reset();
      this.choice.open = false;
      this.sayChoice();
      await this.load();
    } catch (failure) {
      error.textContent = failure.message;
    } finally {
      button.disabled = false;
    }
  }

  onClick(event) {
    const button = event.target.closest("button");
    const item = button?.closest(".target");
    if (!item) return;
    const id = Number(item.dataset.id);
    if (button.classList.contains("test")) this.test(id, button);
    else if (button.classList.contains("delete")) this.remove(id);
  }

  async test(id, button) {
    button.disabled = true;
    const result = $(".test-result", button.parentElement);
    result.className = "test-result";
    result.textContent = "sending…";
    let outcome;
    try {
      const answer = await api("POST", `${TARGETS}/${id}/test`);
      outcome = answer.ok ? { ok: true, text: "sent: check that it arrived" }
        : { ok: false, text: `not sent: ${answer.error}` };
    } catch (failure) {
      outcome = { ok: false, text: failure.message };
    }
    this.tests.set(id, outcome);
    this.render();
    this.load();
  }

  async remove(id) {
    const target = this.targets.find((t) => t.id === id);
    if (!target || !confirm(`Stop sending alarms to ${target.service} (${target.url})?`)) return;
    try {
      await api("DELETE", `${TARGETS}/${id}`);
    } catch (failure) {
      this.tests.set(id, { ok: false, text: failure.message });
    }
    await this.load();
  }
}
