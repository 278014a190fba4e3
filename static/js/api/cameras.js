/* The cameras as this page knows them: the API's listing, the answers to this page's own
   changes and the /ws status messages, each camera no older than the newest of them. */
import { api } from "./client.js";

const SENDING = ["connecting", "live"];  // Camera states in which pictures come.

export function sendsPictures(camera) {
  return SENDING.includes(camera.state);
}

export class Cameras {
  constructor() {
    this.byId = new Map();       // id -> camera
    this.loaded = false;         // a listing has come: a camera missing from it is deleted
    this.statuses = new Map();   // id -> {at, fields}: a camera's latest /ws status, when it came
    this.changedAt = new Map();  // id -> when this page last asked to change the camera
    this.listedAt = 0;           // when the listing last shown was asked for
    this.nodes = 1;              // nodes in the site: with several, each card says its node
  }

  get(id) {
    return this.byId.get(id);
  }

  has(id) {
    return this.byId.has(id);
  }

  values() {
    return this.byId.values();
  }

  name(id) {
    const camera = this.byId.get(id);
    if (camera) return camera.name;
    return this.loaded ? `camera ${id} (deleted)` : `camera ${id}`;
  }

  /* A camera as an answer asked for at askedAt shows it, made no older than what the page
     knows: the fields of a status message that came after the question are newer, but
     for those the request itself set (``set``). */
  answered(id, answer, askedAt, set = []) {
    const status = this.statuses.get(id);
    const newer = status && status.at > askedAt ? { ...status.fields } : {};
    for (const key of set) delete newer[key];
    return { ...(this.byId.get(id) || {}), ...answer, ...newer };
  }

  /* Lists the cameras again: the ids of those deleted since, or null for an answer older
     than the listing already taken (answers may come out of order). */
  async load() {
    const askedAt = performance.now();
    const [cameras, nodes] = await Promise.all([api("GET", "/api/cameras"), api("GET", "/api/nodes")]);
    if (askedAt < this.listedAt) return null;
    this.listedAt = askedAt;
    this.nodes = nodes.length;
    this.loaded = true;
    const seen = new Set();
    for (const camera of cameras) {
      seen.add(camera.id);
      // A camera this page changed since it asked is newer here than in the listing.
      const listed = (this.changedAt.get(camera.id) || 0) > askedAt ? {} : camera;
      this.byId.set(camera.id, this.answered(camera.id, listed, askedAt));
    }
    for (const [id, status] of this.statuses) {
      if (!seen.has(id) && status.at < askedAt) this.statuses.delete(id);  // deleted
    }
    const deleted = Array.from(this.byId.keys()).filter((id) => !seen.has(id));
    for (const id of deleted) {
      this.byId.delete(id);
      this.changedAt.delete(id);
    }
    return deleted;
  }

  add(name, source) {
    return api("POST", "/api/cameras", { name, source });
  }

  remove(id) {
    return api("DELETE", `/api/cameras/${id}`);
  }

  /* Activate, or Stop an active camera. */
  async toggleActive(id) {
    const camera = this.byId.get(id);
    const askedAt = performance.now();
    this.changedAt.set(id, askedAt);
    const updated = await api("POST", `/api/cameras/${id}/${camera && camera.active ? "stop" : "activate"}`);
    this.byId.set(id, this.answered(id, updated, askedAt, ["active"]));
  }

  /* PATCHes the camera; a refusal undoes the change here and is thrown on. */
  async change(id, changes) {
    // Taken at once: a status message that comes before the answer redraws the card from
    // the camera as known here, and would otherwise undo the change on the page (untick
    // "auto" just ticked) until the answer came.
    const before = this.byId.get(id);
    // Not the source: a password typed into it would show on the card until the answer.
    const { source: _, ...shown } = changes;
    this.byId.set(id, { ...before, ...shown });
    const askedAt = performance.now();
    this.changedAt.set(id, askedAt);
    try {
      const updated = await api("PATCH", `/api/cameras/${id}`, changes);
      this.byId.set(id, this.answered(id, updated, askedAt, Object.keys(changes)));
    } catch (error) {
      const undone = Object.fromEntries(Object.keys(changes).map((key) => [key, before && before[key]]));
      this.byId.set(id, { ...this.byId.get(id), ...undone });
      throw error;
    }
  }

  /* A camera's /ws status: kept, and taken into the camera. The camera, or undefined for
     one not listed yet. */
  noteStatus(message) {
    const { type, camera_id: _, storage_error: __, ...fields } = message;
    this.statuses.set(message.camera_id, { at: performance.now(), fields });
    const camera = this.byId.get(message.camera_id);
    if (camera) Object.assign(camera, fields);
    return camera;
  }
}
