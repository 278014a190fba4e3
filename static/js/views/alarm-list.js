/* The Alarms section: one entry per event, made by its first alarm (or from GET
   /api/events on page load), updated by the next alarms of the event and by its
   motion_end. */
import { api } from "../api/client.js";
import { $, escapeHtml } from "../lib/dom.js";
import { formatDate, formatTime, plural } from "../lib/format.js";

const MAX_ENTRIES = 100;
const HISTORY_EVENTS = 50;  // Events listed on page load, from GET /api/events.
const HISTORY_SNAPSHOTS = 2000;  // The most snapshots asked for to show those events'.
/* "Clear list" hides, across reloads, the events that started up to the newest one the
   page had heard of: a time on the server's clock, as the events' started_at are (the
   browser's clock may be off by minutes or hours). */
const CLEARED_KEY = "vigil.alarmsClearedThrough";

function alarmKey(cameraId, eventId, ts) {
  return eventId === null || eventId === undefined ? `c${cameraId}@${ts}` : `e${eventId}`;
}

/* What moved, as an alarm or an event tells it. */
function objectsText(message) {
  const objects = message.objects || [];
  if (objects.length) {
    return objects.map((o) => `#${o.track_id ?? "?"} ${o.box[2]}×${o.box[3]} px at (${o.box[0]}, ${o.box[1]}), `
      + `${Math.round(o.speed_px_s)} px/s`).join(", ");
  }
  return (message.boxes || []).map((b) => `${b[2]}×${b[3]} px at (${b[0]}, ${b[1]})`).join(", ");
}

/* A link that plays the event's clip in the Events section (main.js follows it). */
function playLink(eventId) {
  return eventId === null || eventId === undefined ? ""
    : `<a href="#events" class="open-event" data-event="${Number(eventId)}">play</a>`;
}

/* The toast of an alarm of `name`, the `alarms`th of its event. */
export function alarmToastHtml(message, name, alarms) {
  const repeats = alarms > 1 ? ` <span class="repeats">×${alarms}</span>` : "";
  return `<div class="toast-text"><b>Motion on ${escapeHtml(name)}</b>${repeats}<br>${formatTime(message.ts)} — `
    + `${plural((message.boxes || []).length, "object")} ${playLink(message.event_id)}</div>`
    + (message.snapshot ? `<img src="${message.snapshot}" alt="snapshot">` : "");
}

function setPicture(item, snapshot, difference) {
  if (snapshot && !$("img", item)) {
    $(".shot", item).innerHTML = `<a href="${snapshot}" target="_blank"><img src="${snapshot}" alt=""></a>`;
  }
  if (difference && !$(".links a", item)) {
    $(".links", item).innerHTML = `<a href="${difference}" target="_blank">difference</a>`;
  }
}

function setNoPicture(item, text, title = "") {
  $(".shot", item).innerHTML = `<span class="muted" title="${escapeHtml(title)}">${escapeHtml(text)}</span>`;
}

function setEnded(item, durationS, maxArea) {
  const ongoing = $(".ongoing", item);
  ongoing.textContent = `ended after ${durationS.toFixed(1)} s, peak area ${Math.round(maxArea)} px`;
  ongoing.classList.add("ended");
}

export class AlarmList {
  /* cameraName(id); noteCamera(id) for each camera seen; camerasNoted() after a batch. */
  constructor(list, clearButton, { cameraName, noteCamera, camerasNoted }) {
    this.list = list;
    this.cameraName = cameraName;
    this.noteCamera = noteCamera;
    this.camerasNoted = camerasNoted;
    this.entries = new Map();  // event key -> {item, alarms}: its <li>, the alarms counted
    this.newestEventTs = 0;    // the latest event start (server clock) the page has heard of
    clearButton.addEventListener("click", () => this.clear());
  }

  noteEventTime(ts) {
    if (Number.isFinite(ts) && ts > this.newestEventTs) this.newestEventTs = ts;
  }

  entry(key, cameraId, eventId, started) {
    let entry = this.entries.get(key);
    if (entry) return entry;
    const item = document.createElement("li");
    if (eventId !== null && eventId !== undefined) item.dataset.event = eventId;
    item.dataset.camera = cameraId;
    item.innerHTML = `<span class="shot"><span class="muted">snapshot not saved</span></span>
    <div><b class="who"></b> — <span class="when"></span> <span class="alarms muted"></span><br>
    <span class="objects"></span><br><span class="ongoing">moving…</span> <span class="links"></span> ${playLink(eventId)}</div>`;
    $(".when", item).textContent = formatDate(started);
    entry = { item, alarms: 0 };
    this.entries.set(key, entry);
    return entry;
  }

  /* An alarm of camera `name`, on top of the list: its event's key, and the count of
     the event's alarms so far. */
  add(message, name) {
    this.noteEventTime(message.ts);
    const key = alarmKey(message.camera_id, message.event_id, message.ts);
    const entry = this.entry(key, message.camera_id, message.event_id, message.ts);
    const { item } = entry;
    entry.alarms += 1;
    $(".who", item).textContent = name;
    $(".alarms", item).textContent = entry.alarms > 1 ? `(${entry.alarms} alarms, last at ${formatTime(message.ts)})` : "";
    $(".objects", item).textContent = `${plural((message.boxes || []).length, "object")}: ${objectsText(message)}`;
    // No snapshot when the disk refused it (full, read-only): the event still counts.
    setPicture(item, message.snapshot, message.difference);
    this.list.prepend(item);  // On top: new, or its event moving again.
    this.trim();
    return { key, count: entry.alarms };
  }

  /* A motion_end: the event's entry says how it ended; its key. */
  end(message) {
    const key = alarmKey(message.camera_id, message.event_id, message.ts);
    const entry = this.entries.get(key);
    if (entry) setEnded(entry.item, message.duration_s, message.max_area);
    return key;
  }

  trim() {
    while (this.list.children.length > MAX_ENTRIES) {
      const last = this.list.lastElementChild;
      for (const [key, entry] of this.entries) if (entry.item === last) this.entries.delete(key);
      last.remove();
    }
  }

  /* Snapshots deleted (by this page, or elsewhere as /ws tells): the entries that showed
     them say so. */
  dropSnapshots(urls) {
    for (const { item } of this.entries.values()) {
      const shot = $(".shot a", item);
      if (shot && urls.has(shot.getAttribute("href"))) setNoPicture(item, "snapshot deleted");
      const difference = $(".links a", item);
      if (difference && urls.has(difference.getAttribute("href"))) difference.remove();
    }
  }

  /* The recent events (the list survived no reload before), with their first snapshots. */
  async loadRecent() {
    let events;
    try {
      events = await api("GET", "/api/events?limit=500");
    } catch (_) {
      return;  // Shown on the next action; the live alarms still come.
    }
    for (const event of events) {
      this.noteCamera(event.camera_id);
      this.noteEventTime(event.started_at);
    }
    this.camerasNoted();
    const clearedThrough = Number(localStorage.getItem(CLEARED_KEY) || 0);
    const recent = events.filter((e) => e.started_at > clearedThrough).slice(0, HISTORY_EVENTS);
    if (!recent.length) return;
    const { pictures, listedAll } = await firstSnapshots(recent);
    for (const event of recent) {  // Newest first, after any alarm that came meanwhile.
      const key = alarmKey(event.camera_id, event.id, event.started_at);
      const shown = this.entries.get(key);
      if (shown) {  // Its end may have come while /ws was away (a restart ends it unsaid).
        if (event.ended_at) setEnded(shown.item, event.ended_at - event.started_at, event.max_area);
        continue;
      }
      const { item } = this.entry(key, event.camera_id, event.id, event.started_at);
      $(".who", item).textContent = this.cameraName(event.camera_id);
      $(".objects", item).textContent = `${plural((event.boxes || []).length, "object")}`
        + `${event.boxes && event.boxes.length ? `: ${objectsText(event)}` : ""}`;
      const picture = pictures.get(event.id) || {};
      setPicture(item, picture.frame, picture.difference);
      // None among all listed: none was saved (a full disk), or it has been deleted since.
      if (!picture.frame && listedAll) {
        setNoPicture(item, "no snapshot", "none was saved, or it has been deleted since");
      }
      if (event.ended_at) setEnded(item, event.ended_at - event.started_at, event.max_area);
      this.list.append(item);
    }
    this.trim();
  }

  clear() {
    this.list.innerHTML = "";
    this.entries.clear();
    const clearedThrough = Math.max(Number(localStorage.getItem(CLEARED_KEY) || 0), this.newestEventTs);
    if (clearedThrough > 0) localStorage.setItem(CLEARED_KEY, String(clearedThrough));
  }
}

/* The first snapshots of these events: pictures, event id -> {frame, difference}; and
   listedAll, whether every snapshot since the oldest event was listed (then one missing
   is none kept). */
async function firstSnapshots(events) {
  const pictures = new Map();
  let listedAll = false;
  try {
    const since = Math.min(...events.map((e) => e.started_at)) - 1;
    const snapshots = await api("GET", `/api/snapshots?since=${since}&limit=${HISTORY_SNAPSHOTS}`);
    listedAll = snapshots.length < HISTORY_SNAPSHOTS;
    for (const snap of snapshots) {
      if (snap.event_id === null || snap.event_id === undefined) continue;
      const entry = pictures.get(snap.event_id) || {};
      entry[snap.kind] = snap.url;  // Newest first: the last one seen is the first taken.
      pictures.set(snap.event_id, entry);
    }
  } catch (_) { /* listed without pictures */ }
  return { pictures, listedAll };
}
