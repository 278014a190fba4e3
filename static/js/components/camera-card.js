/* A camera's card: its state, settings and controls, with the parts it owns: pictures,
   motion chart, ignore-zone editor and name-and-source form. */
import { $, escapeHtml, replayAnimation } from "../lib/dom.js";
import { sendsPictures } from "../api/cameras.js";
import { CameraEditForm } from "./camera-edit-form.js";
import { CameraPictures } from "./camera-pictures.js";
import { MotionChart } from "./motion-chart.js";
import { ZoneEditor } from "./zone-editor.js";

const SLIDER_DELAY_MS = 150;  // A slider dragged sends its last value, not every step.

export class CameraCard {
  /* context: cameras (the store), connection (the /ws state), liveFrames (/ws/live),
     toasts, alarmTimes(id), reload() (the camera listing, after a delete). */
  constructor(id, template, context) {
    this.id = id;
    this.cameras = context.cameras;
    this.connection = context.connection;
    this.toasts = context.toasts;
    this.reload = context.reload;
    this.removed = false;
    const card = template.content.firstElementChild.cloneNode(true);
    card.dataset.id = id;
    card.classList.add("no-picture");
    this.element = card;
    this.pictures = new CameraPictures(card, id, {
      cameras: this.cameras,
      connection: this.connection,
      liveFrames: context.liveFrames,
      onSize: () => this.zones.place(),
    });
    this.chart = new MotionChart($(".motion", card), () => context.alarmTimes(id));
    this.wireSettings();
    this.zones = new ZoneEditor(card, {
      savedMask: () => this.cameras.get(id)?.mask,
      save: (mask) => this.patch({ mask }),
      frameSize: () => this.pictures.live.size,
    });
    this.editForm = new CameraEditForm(card, {
      camera: () => this.cameras.get(id) || {},
      save: (changes, report) => this.patch(changes, report),
      sourceChanged: () => this.pictures.restart(),
    });
    $(".delete", card).addEventListener("click", () => this.delete());
  }

  wireSettings() {
    const card = this.element;
    const slider = $(".sensitivity", card);
    const auto = $(".auto", card);
    let sliderTimer = null;
    slider.addEventListener("input", () => {
      $(".sens-value", card).textContent = slider.value;
      auto.checked = false;
      clearTimeout(sliderTimer);
      sliderTimer = setTimeout(() => this.patch({ sensitivity: Number(slider.value) }), SLIDER_DELAY_MS);
    });
    auto.addEventListener("change", () => {
      this.patch({ sensitivity: auto.checked ? null : Number(slider.value) });
    });
    $(".mask", card).addEventListener("change", (e) => this.patch({ show_mask: e.target.checked }));
    $(".min-area", card).addEventListener("change", (e) => {
      const value = Number(e.target.value);
      if (e.target.value !== "" && Number.isFinite(value) && value >= 0) {
        this.patch({ min_area: value });
        return;
      }
      this.toasts.show(`Minimum area of ${escapeHtml(this.cameras.name(this.id))}: a number of pixels, 0 or more`, "error");
      e.target.value = this.cameras.get(this.id)?.min_area ?? "";  // Back to the area in force.
    });
    $(".method", card).addEventListener("change", (e) => this.patch({ method: e.target.value }));
    $(".toggle", card).addEventListener("click", async () => {
      try {
        await this.cameras.toggleActive(this.id);
        this.update();
      } catch (error) {
        this.toasts.show(escapeHtml(error.message), "error");
      }
    });
  }

  async delete() {
    if (!confirm(`Remove camera “${this.cameras.name(this.id)}”? Its snapshots stay.`)) return;
    try {
      await this.cameras.remove(this.id);
      this.reload();
    } catch (error) {
      this.toasts.show(escapeHtml(error.message), "error");
    }
  }

  /* report: where a refusal is said in words (the form that asked), instead of a toast.
     Whether the server took the change. */
  async patch(changes, report = null) {
    let taken = false;
    try {
      await this.cameras.change(this.id, changes);
      taken = true;
    } catch (error) {
      if (report) report(error.message);
      else this.toasts.show(`Cannot change ${escapeHtml(this.cameras.name(this.id))}: ${escapeHtml(error.message)}`, "error");
    }
    this.update();
    return taken;
  }

  /* Shows the camera as known now (after it has been deleted: nothing). */
  update() {
    const camera = this.cameras.get(this.id);
    if (this.removed || !camera) return;
    const card = this.element;
    $(".cam-name", card).textContent = camera.name;
    const source = $(".cam-source", card);
    source.textContent = camera.source;
    source.title = camera.source;
    const node = $(".node", card);  // Where it runs, in a site of several nodes.
    node.hidden = this.cameras.nodes < 2 || !camera.node;
    node.textContent = camera.node ? `on ${camera.node}` : "";
    const badge = $(".state", card);
    const unreachable = this.connection.state === "down";
    // While /ws is down nothing is known of the camera: its last state would be a guess.
    card.classList.toggle("stale", unreachable);
    card.classList.toggle("down", !sendsPictures(camera));
    $(".picture", card).dataset.note = unreachable ? "server unreachable" : `camera ${camera.state || "?"}`;
    if (unreachable) {
      badge.textContent = "server unreachable";
      badge.className = "badge state badge-stale";
      $(".fps", card).textContent = "";
    } else {
      badge.textContent = camera.state || "?";
      badge.className = `badge state badge-${camera.state}`;
      $(".fps", card).textContent = camera.state === "live" ? this.pictures.fpsText(camera) : "";
    }
    $(".reason", card).textContent = unreachable ? "" : camera.reason || "";
    if ("mask" in camera) this.zones.show(camera.mask);
    const toggle = $(".toggle", card);
    toggle.textContent = camera.active ? "Stop" : "Activate";
    toggle.classList.toggle("active", Boolean(camera.active));
    card.classList.toggle("watching", Boolean(camera.active));
    this.showSettings(camera);
    // The histogram is polled once the camera has been live; it carries on across
    // reconnects. (The live picture comes over /ws/live whenever the card is on screen.)
    if (!this.pictures.started && camera.state === "live") this.pictures.start();
  }

  /* The settings, but not in a field the user is changing. */
  showSettings(camera) {
    const card = this.element;
    const slider = $(".sensitivity", card);
    if (document.activeElement !== slider) {
      const automatic = camera.sensitivity === null || camera.sensitivity === undefined;
      $(".auto", card).checked = automatic;
      const threshold = camera.threshold ?? null;  // In force: only while detecting.
      // Automatic: the slider shows the threshold in force, so a nudge starts from there.
      if (!automatic) slider.value = camera.sensitivity;
      else if (threshold !== null) slider.value = Math.round(threshold);
      const inForce = threshold === null ? "" : ` (${Math.round(threshold)})`;
      $(".sens-value", card).textContent = automatic ? `auto${inForce}` : Math.round(camera.sensitivity);
    }
    const minArea = $(".min-area", card);
    if (document.activeElement !== minArea) minArea.value = camera.min_area;
    $(".method", card).value = camera.method;
    $(".mask", card).checked = Boolean(camera.show_mask);
  }

  flash() {
    replayAnimation(this.element, "flash");
  }

  remove() {
    this.removed = true;
    this.pictures.remove();
    this.element.remove();
  }
}
