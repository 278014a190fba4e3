/* A card's name and source. "Edit" opens a form with both, as the camera has them (a
   password in the source shown masked, as the API shows it and takes it back). Enter
   saves, Escape or Cancel leaves it; a refusal is said on the form, which stays open to
   put it right. */
import { $ } from "../lib/dom.js";

const FIELDS = ["name", "source"];

export class CameraEditForm {
  /* camera(): the camera as known; save(changes, report) -> whether the server took them,
     report(message) saying a refusal; sourceChanged() after a new source is taken. */
  constructor(card, { camera, save, sourceChanged }) {
    this.form = $(".edit-form", card);
    this.error = $(".form-error", this.form);
    this.opener = $(".edit", card);
    // What the form showed: only what the user changes is sent, not what others changed since.
    this.opened = null;
    this.opener.addEventListener("click", () => this.open(camera()));
    $(".edit-cancel", this.form).addEventListener("click", () => this.close());
    this.form.addEventListener("keydown", (event) => {
      if (event.key !== "Escape") return;
      event.preventDefault();  // This form's Escape: it closes no toast.
      this.close();
    });
    this.form.addEventListener("submit", async (event) => {
      event.preventDefault();
      const changes = this.changes();
      if (!Object.keys(changes).length) {
        this.close();
        return;
      }
      this.error.textContent = "";
      const button = $("button[type=submit]", this.form);
      button.disabled = true;
      const taken = await save(changes, (message) => { this.error.textContent = message; });
      button.disabled = false;
      if (!taken) return;
      this.close();
      // The server reconnects the camera to its new source: pictures of the old one end.
      if ("source" in changes) sourceChanged();
    });
  }

  open(camera) {
    const { form } = this;
    form.name.value = camera.name ?? "";
    form.source.value = camera.source ?? "";
    this.opened = { name: form.name.value, source: form.source.value };
    this.error.textContent = "";
    form.hidden = false;
    this.opener.setAttribute("aria-expanded", "true");
    form.name.focus();
    form.name.select();
  }

  close() {
    this.form.hidden = true;
    this.error.textContent = "";
    this.opener.setAttribute("aria-expanded", "false");
    this.opener.focus();
  }

  changes() {
    const changes = {};
    for (const key of FIELDS) {
      const value = this.form[key].value.trim();
      if (value !== this.opened[key]) changes[key] = value;
    }
    return changes;
  }
}
