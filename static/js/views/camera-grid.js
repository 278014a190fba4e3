/* The Cameras section: a card per camera, in the order they came, and the form that adds
   one. Every card's picture comes over the page's one /ws/live socket (liveFrames). */
import { $, escapeHtml } from "../lib/dom.js";
import { CameraCard } from "../components/camera-card.js";

const ALARMS_MARKED = 50;  // The latest alarms of a camera drawn on its motion chart.

export class CameraGrid {
  /* listed(): after each listing. */
  constructor({ grid, template, addForm, cameras, connection, liveFrames, toasts, listed }) {
    this.grid = grid;
    this.template = template;
    this.cameras = cameras;
    this.toasts = toasts;
    this.listed = listed;
    this.cards = new Map();       // id -> CameraCard
    // id -> the times of its latest alarms: here, not on the card, as an alarm may come
    // before its camera's card (a camera added elsewhere, not listed yet).
    this.alarmTimes = new Map();
    this.cardContext = {
      cameras, connection, liveFrames, toasts,
      alarmTimes: (id) => this.alarmTimes.get(id) || [],
      reload: () => this.load(),
    };
    addForm.addEventListener("submit", (event) => this.add(event));
  }

  async add(event) {
    event.preventDefault();
    const form = event.target;
    const error = $(".form-error", form);
    error.textContent = "";
    try {
      await this.cameras.add(form.name.value.trim(), form.source.value.trim());
      form.reset();
      this.load();
    } catch (failure) {
      error.textContent = failure.message;
    }
  }

  /* Lists the cameras again: new ones get a card, deleted ones lose theirs. */
  async load() {
    try {
      const deleted = await this.cameras.load();
      if (deleted === null) return;
      for (const id of deleted) {
        this.cards.get(id)?.remove();
        this.cards.delete(id);
      }
      this.render();
      this.listed();
    } catch (error) {
      this.toasts.show(`Cannot load cameras: ${escapeHtml(error.message)}`, "error");
    }
  }

  render() {
    for (const camera of this.cameras.values()) {
      if (!this.cards.has(camera.id)) {
        const card = new CameraCard(camera.id, this.template, this.cardContext);
        this.cards.set(camera.id, card);
        this.grid.append(card.element);
      }
    }
    for (const camera of this.cameras.values()) this.cards.get(camera.id).update();
  }

  /* A camera's /ws status message. */
  onStatus(message) {
    const camera = this.cameras.noteStatus(message);
    if (!camera) {
      this.load();
      return;
    }
    if ("storage_error" in message) {
      const name = escapeHtml(camera.name);
      if (message.storage_error) {
        this.toasts.show(`<b>Snapshots of ${name} not saved:</b> ${escapeHtml(message.storage_error)}`, "error");
      } else {
        this.toasts.show(`Snapshots of ${name} are saved again`, "info");
      }
    }
    const card = this.cards.get(message.camera_id);
    card?.update();
    card?.chart.record(Date.now() / 1000, message.motion || 0);
  }

  /* An alarm: marked on the camera's chart, and its card flashes. */
  onAlarm(cameraId, ts) {
    const times = this.alarmTimes.get(cameraId) || [];
    times.push(ts);
    this.alarmTimes.set(cameraId, times.slice(-ALARMS_MARKED));
    this.cards.get(cameraId)?.flash();
  }

  updateAll() {
    for (const card of this.cards.values()) card.update();
  }

  drawCharts(now) {
    for (const card of this.cards.values()) card.chart.draw(now);
  }
}
