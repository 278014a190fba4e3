/* Vigil dashboard: plain JS, no build step. Talks to /api/* and listens on /ws. */
"use strict";

const $ = (selector, root = document) => root.querySelector(selector);
const $$ = (selector, root = document) => Array.from(root.querySelectorAll(selector));

/* Browsers keep about six HTTP/1.1 connections per host. An MJPEG stream holds one for
   as long as it is shown, so at most STREAM_BUDGET pictures are streams (the first cards,
   less the analyses being watched live) and two connections stay free for API calls,
   histograms and the pictures of the other cameras, which are polled as single frames:
   the next as soon as the last has loaded (the server answers when the camera has a new
   one), at most MAX_POLL_FPS a second. */
const STREAM_BUDGET = 4;
const MAX_POLL_FPS = 30;
const HISTOGRAM_MS = 1000;
const MOTION_WINDOW_S = 60;
const SENDING = ["connecting", "live"];  // Camera states in which pictures come.
const STALL_MS = 10000;  // A stream of a live camera whose picture stays the same this long is reopened.
const TOAST_MAX = 3;     // Toasts shown at once; the rest wait behind "+N more".
const CLOSED_TOASTS_MAX = 500;  // Alarm toasts closed by the user, remembered until their event ends.
const ALARM_LIST_MAX = 100;
const HISTORY_EVENTS = 50;  // Events listed on page load, from GET /api/events.
const HISTORY_SNAPSHOTS = 2000;  // The most snapshots asked for to show those events'.
const GALLERY_PAGE = 200;   // Snapshots the gallery shows at first, and adds on "Show older".
const GALLERY_MAX = 9999;   // The most shown: one more than this is the most one listing gives.

const state = {
  cameras: new Map(),      // id -> camera (from the API, updated by /ws status)
  cards: new Map(),        // id -> card element
  motion: new Map(),       // id -> [{t, v}]
  alarmsAt: new Map(),     // id -> [t]
  muted: localStorage.getItem("vigil.muted") === "1",
  ws: "connecting",        // the /ws connection: connecting, up, down (server unreachable)
  wsEverUp: false,
  camerasLoaded: false,
  knownCameraIds: new Set(),  // cameras that have events or snapshots, deleted ones too
  alarmItems: new Map(),   // event key -> alarm list entry
  closedToasts: new Set(), // keys of the alarm toasts the user closed, oldest first
  analyses: new Map(),     // id -> element
  uploads: new Set(),      // the uploads under way (XMLHttpRequest)
  newestEventTs: 0,        // the latest event start (server clock) the page has heard of
  statuses: new Map(),     // id -> {at, fields}: a camera's latest /ws status, when it came
  changedAt: new Map(),    // id -> when this page last asked to change the camera
  listedAt: 0,             // when the camera listing last shown was asked for
  // The snapshot gallery: the filters it shows, what it shows (newest first), whether
  // older ones match too, the oldest it has shown (where older ones start), the ids of
  // those shown that have been deleted elsewhere; its listings, one after another (each
  // builds on what the last showed), and the refresh that waits for its turn, if any.
  gallery: {
    filters: null, snapshots: [], more: false, oldest: null, gone: new Set(),
    queue: Promise.resolve(), waiting: null,
  },
};

/* ---------- HTTP ---------- */

/* A 401 means the session has ended (or never began): log in, then come back here. */
function toLogin() {
  location.assign(`/login?next=${encodeURIComponent(location.pathname + location.search)}`);
}

async function api(method, url, body) {
  const options = { method, headers: {} };
  if (body !== undefined) {
    options.headers["Content-Type"] = "application/json";
    options.body = JSON.stringify(body);
  }
  let response;
  try {
    response = await fetch(url, options);
  } catch (_) {
    // No answer at all (server down, network gone): the browser's own words ("Failed to
    // fetch") tell a user nothing.
    throw new Error("Server unreachable: try again when it is back");
  }
  if (response.status === 401) {
    toLogin();
    throw new Error("logged out");
  }
  if (!response.ok) {
    let detail = response.statusText;
    try {
      const data = await response.json();
      detail = typeof data.detail === "string" ? data.detail
        : (data.detail || []).map((d) => d.msg).join("; ") || detail;
    } catch (_) { /* not JSON */ }
    throw new Error(detail);
  }
  return response.status === 204 ? null : response.json();
}

function fmtTime(ts) {
  return new Date(ts * 1000).toLocaleTimeString();
}

function fmtDate(ts) {
  return new Date(ts * 1000).toLocaleString();
}

/* The sticky header's height, for the sections' scroll-margin-top: a nav link brings its
   section's heading just below the header, not under it (it wraps on narrow screens). */
new ResizeObserver(() => {
  document.documentElement.style.setProperty("--top-height", `${$(".top").offsetHeight}px`);
}).observe($(".top"));

/* ---------- Sound and toasts ---------- */

/* Browsers let a page play sound only once the user has clicked or typed on it (the
   autoplay policy). Until then the sound button says "click to enable sound"; the first
   click or key press anywhere on the page unlocks it. */
let audio = null;
/* Whether the press under way (the last pointerdown or key press on the page) began on
   the sound button while it asked to enable sound: the click that press ends in enables
   sound and does not mute. Every new press decides afresh, so a Tab away from the button
   or a press dragged off it leaves nothing behind for the next click. */
let pressUnlocks = false;

function audioReady() {
  return Boolean(audio && audio.state === "running");
}

function soundLocked() {
  return !state.muted && Boolean(window.AudioContext) && !audioReady();
}

function notePress(event) {
  // Enter and Space are the keys that click a focused button.
  const activates = event.type === "pointerdown" || event.key === "Enter" || event.key === " ";
  pressUnlocks = activates && $("#mute").contains(event.target) && soundLocked();
}

document.addEventListener("pointerdown", notePress, { capture: true });
document.addEventListener("keydown", notePress, { capture: true });

function unlockAudio() {
  if (!window.AudioContext || audioReady()) return;
  if (!audio) {
    audio = new AudioContext();
    audio.addEventListener("statechange", renderMute);
  }
  audio.resume().then(renderMute, () => {});
  renderMute();
}

for (const type of ["pointerdown", "keydown", "touchend"]) {
  document.addEventListener(type, unlockAudio, { capture: true });
}

function beep() {
  if (state.muted) return;
  if (!audioReady()) {
    // No sound yet: draw the eye to the button that enables it.
    const button = $("#mute");
    button.classList.remove("nudge");
    void button.offsetWidth;
    button.classList.add("nudge");
    return;
  }
  const now = audio.currentTime;
  for (const [offset, freq] of [[0, 880], [0.18, 660]]) {
    const osc = audio.createOscillator();
    const gain = audio.createGain();
    osc.type = "square";
    osc.frequency.value = freq;
    gain.gain.setValueAtTime(0.08, now + offset);
    gain.gain.exponentialRampToValueAtTime(0.0001, now + offset + 0.15);
    osc.connect(gain).connect(audio.destination);
    osc.start(now + offset);
    osc.stop(now + offset + 0.16);
  }
}

function renderMute() {
  const button = $("#mute");
  const locked = soundLocked();
  $(".label", button).textContent = state.muted ? "Sound off" : locked ? "Click to enable sound" : "Sound on";
  button.classList.toggle("locked", locked);
  button.setAttribute("aria-pressed", String(state.muted));
  button.title = locked ? "the browser plays sound only after a click or a key press on the page"
    : state.muted ? "alarm sound is off: click to turn it on" : "alarm sound is on: click to mute";
}

$("#mute").addEventListener("click", () => {
  if (pressUnlocks) {
    pressUnlocks = false;
    return;
  }
  state.muted = !state.muted;
  localStorage.setItem("vigil.muted", state.muted ? "1" : "0");
  renderMute();
});

/* Toasts: at most TOAST_MAX shown, newest first; the rest wait behind "+N more" (with
   "dismiss all"). A toast with a key (an alarm: its camera and event) is updated in
   place by the next one with the same key rather than stacked again. A click on a toast,
   its close button (Tab reaches it) or Escape (the newest) closes it; an alarm's toast
   closed so stays closed while its event goes on (it alarms again every second or so, and
   the user closed it to reach what it covered): the alarm list still counts the alarms.
   Returns the toast, or null for one the user closed. */
function toast(html, kind = "alarm", key = null) {
  const box = $("#toasts");
  key = key || `${kind}:${html}`;
  if (state.closedToasts.has(key)) return null;
  let el = findToast(key);
  if (el) {
    clearTimeout(el._timer);
    el._repeats = (el._repeats || 1) + 1;
  } else {
    el = document.createElement("div");
    el.className = `toast toast-${kind}`;
    el.dataset.key = key;
    el.setAttribute("role", kind === "error" ? "alert" : "status");
    el.addEventListener("click", () => closeToast(el));
    el._repeats = 1;
  }
  const focused = el.contains(document.activeElement);  // Its close button, kept focused.
  el.innerHTML = html + (el._repeats > 1 && kind !== "alarm" ? ` <span class="repeats">×${el._repeats}</span>` : "")
    + '<button type="button" class="toast-close" aria-label="close this message" title="close (Esc closes the newest)">✕</button>';
  if (focused) $(".toast-close", el).focus();
  box.prepend(el);
  el._timer = setTimeout(() => removeToast(el), kind === "error" ? 12000 : 8000);
  layoutToasts();
  return el;
}

function findToast(key) {
  return $$("#toasts > .toast").find((t) => t.dataset.key === key);
}

/* Closed by the user (not timed out): an alarm's stays closed until its event ends. */
function closeToast(el) {
  if (el.classList.contains("toast-alarm")) {
    state.closedToasts.add(el.dataset.key);
    // Bounded: an event whose end never comes (a server restart) is not kept for ever.
    if (state.closedToasts.size > CLOSED_TOASTS_MAX) {
      state.closedToasts.delete(state.closedToasts.values().next().value);
    }
  }
  removeToast(el);
}

function removeToast(el) {
  const hadFocus = el.contains(document.activeElement);
  clearTimeout(el._timer);
  el.remove();
  layoutToasts();
  // Closed from the keyboard: on to the next toast's close button, if any.
  if (hadFocus) $("#toasts > .toast:not([hidden]) .toast-close")?.focus();
}

function layoutToasts() {
  const toasts = $$("#toasts > .toast");
  toasts.forEach((el, i) => { el.hidden = i >= TOAST_MAX; });
  const more = $("#toasts-more");
  const hidden = toasts.length - TOAST_MAX;
  more.hidden = hidden <= 0;
  $(".count", more).textContent = hidden > 0 ? `+${hidden} more` : "";
}

$("#toasts-dismiss").addEventListener("click", () => {
  for (const el of $$("#toasts > .toast")) closeToast(el);
});

document.addEventListener("keydown", (event) => {
  // Not an Escape that something else took (a form on a card closes with it).
  if (event.key !== "Escape" || event.defaultPrevented) return;
  const chosen = document.activeElement?.closest("#toasts > .toast") || $("#toasts > .toast");
  if (chosen) closeToast(chosen);
});

function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => ({
    "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}

/* ---------- Cameras ---------- */

function cameraName(id) {
  const camera = state.cameras.get(id);
  if (camera) return camera.name;
  return state.camerasLoaded ? `camera ${id} (deleted)` : `camera ${id}`;
}

/* A camera as an answer asked for at askedAt shows it, made no older than what the page
   knows: the fields of a status message that came after the question are newer, but
   for those the request itself set (``set``). */
function answered(id, answer, askedAt, set = []) {
  const status = state.statuses.get(id);
  const newer = status && status.at > askedAt ? { ...status.fields } : {};
  for (const key of set) delete newer[key];
  return { ...(state.cameras.get(id) || {}), ...answer, ...newer };
}

async function loadCameras() {
  const askedAt = performance.now();
  try {
    const cameras = await api("GET", "/api/cameras");
    // Answers may come out of order: one asked for before the listing shown is older.
    if (askedAt < state.listedAt) return;
    state.listedAt = askedAt;
    state.camerasLoaded = true;
    const seen = new Set();
    for (const camera of cameras) {
      seen.add(camera.id);
      // A camera this page changed since it asked is newer here than in the listing.
      const listed = (state.changedAt.get(camera.id) || 0) > askedAt ? {} : camera;
      state.cameras.set(camera.id, answered(camera.id, listed, askedAt));
    }
    for (const [id, status] of state.statuses) {
      if (!seen.has(id) && status.at < askedAt) state.statuses.delete(id);  // deleted
    }
    for (const id of Array.from(state.cameras.keys())) {
      if (!seen.has(id)) {
        state.cameras.delete(id);
        state.changedAt.delete(id);
        const card = state.cards.get(id);
        if (card) {
          stopPictures(card);
          card.remove();
        }
        state.cards.delete(id);
      }
    }
    renderCameras();
    renderCameraFilter();
  } catch (error) {
    toast(`Cannot load cameras: ${escapeHtml(error.message)}`, "error");
  }
}

function renderCameras() {
  for (const camera of state.cameras.values()) {
    if (!state.cards.has(camera.id)) {
      const card = makeCard(camera.id);
      state.cards.set(camera.id, card);
      $("#grid").append(card);
    }
  }
  assignPictureModes();
  for (const camera of state.cameras.values()) updateCard(state.cards.get(camera.id), camera);
}

/* Which pictures are streams: the first cards, as many as the connection budget allows. */
function assignPictureModes() {
  const slots = Math.max(0, STREAM_BUDGET - $$("#analyses .live-view img.streaming").length);
  $$("#grid > .card").forEach((card, i) => {
    const mode = i < slots ? "stream" : "poll";
    if (card._mode === mode) return;
    card._mode = mode;
    card.classList.toggle("polled", mode === "poll");
    if (card._started) restartPictures(card, true);
  });
}

function makeCard(id) {
  const card = $("#camera-card").content.firstElementChild.cloneNode(true);
  card.dataset.id = id;
  const slider = $(".sensitivity", card);
  const auto = $(".auto", card);
  const output = $(".sens-value", card);
  let timer = null;
  slider.addEventListener("input", () => {
    output.textContent = slider.value;
    auto.checked = false;
    clearTimeout(timer);
    timer = setTimeout(() => patchCamera(id, { sensitivity: Number(slider.value) }), 150);
  });
  auto.addEventListener("change", () => {
    patchCamera(id, { sensitivity: auto.checked ? null : Number(slider.value) });
  });
  $(".mask", card).addEventListener("change", (e) => patchCamera(id, { show_mask: e.target.checked }));
  $(".min-area", card).addEventListener("change", (e) => {
    const value = Number(e.target.value);
    if (e.target.value !== "" && Number.isFinite(value) && value >= 0) {
      patchCamera(id, { min_area: value });
      return;
    }
    toast(`Minimum area of ${escapeHtml(cameraName(id))}: a number of pixels, 0 or more`, "error");
    e.target.value = state.cameras.get(id)?.min_area ?? "";  // Back to the area in force.
  });
  $(".method", card).addEventListener("change", (e) => patchCamera(id, { method: e.target.value }));
  $(".toggle", card).addEventListener("click", async () => {
    const camera = state.cameras.get(id);
    try {
      const askedAt = performance.now();
      state.changedAt.set(id, askedAt);
      const updated = await api("POST", `/api/cameras/${id}/${camera && camera.active ? "stop" : "activate"}`);
      state.cameras.set(id, answered(id, updated, askedAt, ["active"]));
      updateCard(card, state.cameras.get(id));
    } catch (error) {
      toast(escapeHtml(error.message), "error");
    }
  });
  setUpZones(card, id);
  setUpEditing(card, id);
  $(".delete", card).addEventListener("click", async () => {
    if (!confirm(`Remove camera “${cameraName(id)}”? Its snapshots stay.`)) return;
    try {
      await api("DELETE", `/api/cameras/${id}`);
      loadCameras();
    } catch (error) {
      toast(escapeHtml(error.message), "error");
    }
  });
  return card;
}

/* ---------- Name and source ---------- */
// "Edit" opens a form on the card with both, as the camera has them (a password in the
// source shown masked, as the API shows it and takes it back). Enter saves, Escape or
// Cancel leaves it; a refusal is said on the form, which stays open to put it right.

function setUpEditing(card, id) {
  const form = $(".edit-form", card);
  const error = $(".form-error", form);
  const open = $(".edit", card);
  const close = () => {
    form.hidden = true;
    error.textContent = "";
    open.setAttribute("aria-expanded", "false");
    open.focus();
  };
  open.addEventListener("click", () => {
    const camera = state.cameras.get(id) || {};
    form.name.value = camera.name ?? "";
    form.source.value = camera.source ?? "";
    // What it showed: only what the user changes is sent, not what others changed since.
    form._opened = { name: form.name.value, source: form.source.value };
    error.textContent = "";
    form.hidden = false;
    open.setAttribute("aria-expanded", "true");
    form.name.focus();
    form.name.select();
  });
  $(".edit-cancel", form).addEventListener("click", close);
  form.addEventListener("keydown", (event) => {
    if (event.key !== "Escape") return;
    event.preventDefault();  // This form's Escape: it closes no toast.
    close();
  });
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const changes = {};
    for (const key of ["name", "source"]) {
      const value = form[key].value.trim();
      if (value !== form._opened[key]) changes[key] = value;
    }
    if (!Object.keys(changes).length) {
      close();
      return;
    }
    error.textContent = "";
    const save = $("button[type=submit]", form);
    save.disabled = true;
    const taken = await patchCamera(id, changes, (message) => { error.textContent = message; });
    save.disabled = false;
    if (!taken) return;
    close();
    // The server reconnects the camera to its new source: pictures of the old one end.
    if ("source" in changes) restartPictures(card);
  });
}

/* ---------- Ignore zones ---------- */
// Polygons of [x, y] fractions of the frame (the API's `mask`), drawn in an SVG laid
// exactly over the picture as `object-fit: contain` shows it.

const SVG = "http://www.w3.org/2000/svg";

function setUpZones(card, id) {
  const picture = $(".picture", card);
  const img = $(".live", card);
  const layer = document.createElementNS(SVG, "svg");
  layer.classList.add("zone-layer");
  layer.setAttribute("viewBox", "0 0 1 1");
  layer.setAttribute("preserveAspectRatio", "none");
  picture.append(layer);
  const editor = { zones: [], draft: [] };
  card._zones = editor;

  const place = () => {
    if (!img.naturalWidth) return;
    const box = picture.getBoundingClientRect();
    const scale = Math.min(box.width / img.naturalWidth, box.height / img.naturalHeight);
    const width = img.naturalWidth * scale;
    const height = img.naturalHeight * scale;
    layer.style.left = `${(box.width - width) / 2}px`;
    layer.style.top = `${(box.height - height) / 2}px`;
    layer.style.width = `${width}px`;
    layer.style.height = `${height}px`;
  };
  const draw = () => {
    place();
    layer.replaceChildren();
    for (const zone of editor.zones) {
      const polygon = document.createElementNS(SVG, "polygon");
      polygon.setAttribute("points", zone.map(([x, y]) => `${x},${y}`).join(" "));
      layer.append(polygon);
    }
    if (editor.draft.length) {
      const line = document.createElementNS(SVG, "polyline");
      line.classList.add("draft");
      line.setAttribute("points", editor.draft.map(([x, y]) => `${x},${y}`).join(" "));
      layer.append(line);
      for (const [x, y] of editor.draft) {
        const dot = document.createElementNS(SVG, "circle");
        dot.setAttribute("cx", x);
        dot.setAttribute("cy", y);
        dot.setAttribute("r", 0.008);
        layer.append(dot);
      }
    }
  };
  let shown = null;  // The mask last drawn: status messages repeat it every second.
  editor.show = (mask) => {
    if (card.classList.contains("editing-zones")) return;  // Not while someone draws.
    const text = JSON.stringify(mask || []);
    if (text === shown) return;
    shown = text;
    editor.zones = (mask || []).map((zone) => zone.map(([x, y]) => [x, y]));
    draw();
  };
  const finishDraft = () => {
    if (editor.draft.length >= 3) editor.zones.push(editor.draft);
    editor.draft = [];
  };
  const stopEditing = () => {
    card.classList.remove("editing-zones");
    $(".zone-tools", card).hidden = true;
    editor.draft = [];
    shown = null;  // The drawing may differ from the saved mask: draw that again.
    editor.show(state.cameras.get(id)?.mask);
  };
  img.addEventListener("load", place);
  new ResizeObserver(draw).observe(picture);  // Gone with the card, unlike a window listener.
  layer.addEventListener("click", (event) => {
    const box = layer.getBoundingClientRect();
    const round = (value) => Math.round(Math.min(1, Math.max(0, value)) * 1000) / 1000;
    editor.draft.push([round((event.clientX - box.left) / box.width), round((event.clientY - box.top) / box.height)]);
    draw();
  });
  $(".zones", card).addEventListener("click", () => {
    card.classList.add("editing-zones");
    $(".zone-tools", card).hidden = false;
    draw();
  });
  $(".zone-finish", card).addEventListener("click", () => { finishDraft(); draw(); });
  $(".zone-clear", card).addEventListener("click", () => { editor.zones = []; editor.draft = []; draw(); });
  $(".zone-cancel", card).addEventListener("click", stopEditing);
  $(".zone-save", card).addEventListener("click", async () => {
    finishDraft();
    const zones = editor.zones;
    card.classList.remove("editing-zones");
    await patchCamera(id, { mask: zones.length ? zones : null });
    stopEditing();
  });
}

/* report: where a refusal is said in words (the form that asked), instead of a toast.
   Whether the server took the change. */
async function patchCamera(id, changes, report = null) {
  // Taken at once: a status message that comes before the answer redraws the card from
  // the camera as known here, and would otherwise undo the change on the page (untick
  // "auto" just ticked) until the answer came.
  const before = state.cameras.get(id);
  // Not the source: a password typed into it would show on the card until the answer.
  const { source: _, ...shown } = changes;
  state.cameras.set(id, { ...before, ...shown });
  const askedAt = performance.now();
  state.changedAt.set(id, askedAt);
  let taken = false;
  try {
    const updated = await api("PATCH", `/api/cameras/${id}`, changes);
    state.cameras.set(id, answered(id, updated, askedAt, Object.keys(changes)));
    taken = true;
  } catch (error) {
    const undone = Object.fromEntries(Object.keys(changes).map((key) => [key, before && before[key]]));
    state.cameras.set(id, { ...state.cameras.get(id), ...undone });
    if (report) report(error.message);
    else toast(`Cannot change ${escapeHtml(cameraName(id))}: ${escapeHtml(error.message)}`, "error");
  }
  updateCard(state.cards.get(id), state.cameras.get(id));
  return taken;
}

function updateCard(card, camera) {
  if (!card || !camera) return;
  $(".cam-name", card).textContent = camera.name;
  $(".cam-source", card).textContent = camera.source;
  $(".cam-source", card).title = camera.source;
  const badge = $(".state", card);
  const unreachable = state.ws === "down";
  // While /ws is down nothing is known of the camera: its last state would be a guess.
  card.classList.toggle("stale", unreachable);
  card.classList.toggle("down", !SENDING.includes(camera.state));
  $(".picture", card).dataset.note = unreachable ? "server unreachable" : `camera ${camera.state || "?"}`;
  if (unreachable) {
    badge.textContent = "server unreachable";
    badge.className = "badge state badge-stale";
    $(".fps", card).textContent = "";
  } else {
    badge.textContent = camera.state || "?";
    badge.className = `badge state badge-${camera.state}`;
    $(".fps", card).textContent = camera.state === "live" ? fpsText(card, camera) : "";
  }
  $(".reason", card).textContent = unreachable ? "" : camera.reason || "";
  if (card._zones && "mask" in camera) card._zones.show(camera.mask);
  const toggle = $(".toggle", card);
  toggle.textContent = camera.active ? "Stop" : "Activate";
  toggle.classList.toggle("active", Boolean(camera.active));
  card.classList.toggle("watching", Boolean(camera.active));
  const slider = $(".sensitivity", card);
  const auto = $(".auto", card);
  if (document.activeElement !== slider) {
    const automatic = camera.sensitivity === null || camera.sensitivity === undefined;
    auto.checked = automatic;
    const threshold = camera.threshold ?? null;  // In force: only while detecting.
    // Automatic: the slider shows the threshold in force, so a nudge starts from there.
    if (!automatic) slider.value = camera.sensitivity;
    else if (threshold !== null) slider.value = Math.round(threshold);
    const inForce = threshold === null ? "" : ` (${Math.round(threshold)})`;
    $(".sens-value", card).textContent = automatic ? `auto${inForce}` : Math.round(camera.sensitivity);
  }
  if (document.activeElement !== $(".min-area", card)) $(".min-area", card).value = camera.min_area;
  $(".method", card).value = camera.method;
  $(".mask", card).checked = Boolean(camera.show_mask);
  // Pictures start once the camera has been live (a stream from a dead source would
  // hold a connection with nothing to show); they carry on across reconnects.
  if (!card._started && camera.state === "live") startPictures(card, camera.id);
  card.classList.toggle("no-picture", !card._started);
}

function fpsText(card, camera) {
  const fps = `${(camera.fps || 0).toFixed(1)} fps`;
  if (card._mode !== "poll") return fps;
  const now = performance.now();
  const shown = (card._shown || []).filter((t) => t > now - 5000);
  card._shown = shown;
  return `${fps} · ${(shown.length / 5).toFixed(1)} shown/s`;
}

/* Whether a polled picture of this card may be asked for now: not while the server is
   unreachable, the camera is down (the answer would be a 503) or the page is hidden. */
function canFetch(card) {
  const camera = state.cameras.get(Number(card.dataset.id));
  return state.ws !== "down" && !document.hidden && Boolean(camera) && SENDING.includes(camera.state);
}

function startPictures(card, id) {
  const img = $(".live", card);
  const hist = $(".histogram", card);
  card._timers = [];
  card._loops = [];
  card._started = true;
  card._still = null;
  if (card._mode === "poll") {
    const minMs = () => 1000 / Math.min(MAX_POLL_FPS, Math.max(1, state.cameras.get(id)?.fps || 0));
    card._loops.push(pollLoop(card, img, `/api/cameras/${id}/frame.jpg`, minMs, () => {
      (card._shown = card._shown || []).push(performance.now());
    }));
  } else if (document.hidden) {
    blankPicture(img);  // A hidden page holds no stream (see "visibilitychange").
  } else {
    img.onload = () => img.classList.remove("broken");
    img.onerror = () => {
      img.classList.add("broken");
      // While the server is away the /ws reconnect reopens every picture.
      if (state.ws !== "down") card._timers.push(setTimeout(() => restartPictures(card), 2000));
    };
    img.src = `/api/cameras/${id}/stream.mjpg?r=${Date.now()}`;
  }
  card._loops.push(pollLoop(card, hist, `/api/cameras/${id}/histogram.jpg`, () => HISTOGRAM_MS));
}

/* Asks for the next picture as soon as the last one has loaded, no sooner than every
   minMs() milliseconds; waits without asking while canFetch says no. */
function pollLoop(card, img, url, minMs, onFrame = null) {
  const loop = { timer: null, started: 0, stopped: false };
  const go = () => {
    if (loop.stopped) return;
    if (!canFetch(card)) {
      loop.timer = setTimeout(go, 500);
      return;
    }
    loop.started = performance.now();
    img.src = `${url}?t=${Date.now()}`;
  };
  img.onload = () => {
    img.classList.remove("broken");
    if (onFrame) onFrame();
    if (!loop.stopped) loop.timer = setTimeout(go, Math.max(0, minMs() - (performance.now() - loop.started)));
  };
  img.onerror = () => {
    img.classList.add("broken");  // No broken-image icon: the last picture or nothing.
    if (!loop.stopped) loop.timer = setTimeout(go, 1000);
  };
  go();
  return loop;
}

/* Stop asking for pictures; keep: leave the last ones shown (they are replaced next). */
function stopPictures(card, keep = false) {
  for (const timer of card._timers || []) clearTimeout(timer);
  for (const loop of card._loops || []) {
    loop.stopped = true;
    clearTimeout(loop.timer);
  }
  card._timers = [];
  card._loops = [];
  for (const img of $$("img", card)) {
    img.onload = null;
    img.onerror = null;
    if (!keep) img.removeAttribute("src");
  }
}

/* modeChanged: the picture goes from a stream to polled frames or back. The old src
   goes at once: a polled picture is asked for only when canFetch allows (not while the
   page is hidden or the server unreachable), and until then the old src would hold its
   MJPEG connection open. Nothing is shown (no alt text) until the first new picture. */
function restartPictures(card, modeChanged = false) {
  if (!card._started) return;
  stopPictures(card, true);
  if (modeChanged) blankPicture($(".live", card));
  startPictures(card, Number(card.dataset.id));
}

/* No picture, and no connection held for one, until the next src. */
function blankPicture(img) {
  img.removeAttribute("src");
  img.classList.add("broken");
}

/* A tab in the background keeps its connections: a forgotten one with its streams open
   leaves too few for a new tab of the dashboard, whose requests would then wait for
   ever. A hidden page closes its streams (polled pictures already wait while it is
   hidden) and opens them again when shown. */
document.addEventListener("visibilitychange", () => {
  for (const card of state.cards.values()) if (card._mode !== "poll") restartPictures(card);
  showAnalysisStreams();
});

/* An MJPEG <img> fires no event when its stream ends or stalls: it just keeps the last
   picture. Every few seconds the picture of each streamed live camera is sampled; one
   that has not changed for STALL_MS is reopened. (A camera that sends the very same
   picture for that long is reopened too, which costs one request.) */
const sampler = document.createElement("canvas");
sampler.width = 16;
sampler.height = 12;
const sampleContext = sampler.getContext("2d", { willReadFrequently: true });

function pictureHash(img) {
  try {
    sampleContext.drawImage(img, 0, 0, sampler.width, sampler.height);
    const data = sampleContext.getImageData(0, 0, sampler.width, sampler.height).data;
    let hash = 0;
    for (let i = 0; i < data.length; i += 4) hash = (hash * 31 + data[i] + 7 * data[i + 1] + 13 * data[i + 2]) >>> 0;
    return hash;
  } catch (_) {
    return null;
  }
}

function watchStreams() {
  const now = Date.now();
  for (const [id, card] of state.cards) {
    const camera = state.cameras.get(id);
    const img = $(".live", card);
    if (!card._started || card._mode === "poll" || state.ws !== "up" || document.hidden
        || !camera || camera.state !== "live" || !(camera.fps >= 1) || !img.naturalWidth) {
      card._still = null;
      continue;
    }
    const hash = pictureHash(img);
    if (hash === null) continue;
    if (!card._still || card._still.hash !== hash) card._still = { hash, since: now };
    else if (now - card._still.since >= STALL_MS) restartPictures(card);
  }
}

function recordMotion(id, ts, value) {
  const series = state.motion.get(id) || [];
  series.push({ t: ts, v: value });
  while (series.length && series[0].t < ts - MOTION_WINDOW_S) series.shift();
  state.motion.set(id, series);
  drawMotion(id, ts);
}

function motionChart(card) {
  if (card._chart || !window.uPlot) return card._chart || null;
  const el = $(".motion", card);
  const width = Math.max(120, el.clientWidth || 256);
  card._chart = new uPlot({
    width, height: 120,
    legend: { show: false },
    cursor: { show: false },
    scales: { x: { time: true }, y: { range: (u, min, max) => [0, Math.max(0.5, max * 1.1)] } },
    axes: [
      { stroke: "#8b95a3", grid: { stroke: "#2c333d" }, ticks: { stroke: "#2c333d" }, size: 24 },
      { stroke: "#8b95a3", grid: { stroke: "#2c333d" }, ticks: { stroke: "#2c333d" }, size: 36 },
    ],
    series: [{}, { label: "motion %", stroke: "#6cf", width: 1.5, fill: "rgba(102,204,255,0.15)" }],
    hooks: {
      draw: [(u) => {
        const alarms = state.alarmsAt.get(Number(card.dataset.id)) || [];
        const ctx = u.ctx;
        ctx.save();
        ctx.strokeStyle = "#e5484d";
        ctx.lineWidth = 2;
        for (const t of alarms) {
          const x = u.valToPos(t, "x", true);
          if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) continue;
          ctx.beginPath();
          ctx.moveTo(x, u.bbox.top);
          ctx.lineTo(x, u.bbox.top + u.bbox.height);
          ctx.stroke();
        }
        ctx.restore();
      }],
    },
  }, [[], []], el);
  new ResizeObserver(() => {
    const fit = Math.max(120, el.clientWidth);
    if (Math.abs(fit - card._chart.width) > 2) card._chart.setSize({ width: fit, height: 120 });
  }).observe(el);
  return card._chart;
}

function drawMotion(id, now) {
  const card = state.cards.get(id);
  if (!card) return;
  const chart = motionChart(card);
  if (!chart) return;
  const series = (state.motion.get(id) || []).filter((p) => p.t >= now - MOTION_WINDOW_S);
  chart.setData([series.map((p) => p.t), series.map((p) => p.v * 100)], false);
  chart.setScale("x", { min: now - MOTION_WINDOW_S, max: now });
}

$("#add-camera").addEventListener("submit", async (event) => {
  event.preventDefault();
  const form = event.target;
  $("#add-camera-error").textContent = "";
  try {
    await api("POST", "/api/cameras", { name: form.name.value.trim(), source: form.source.value.trim() });
    form.reset();
    loadCameras();
  } catch (error) {
    $("#add-camera-error").textContent = error.message;
  }
});

/* ---------- Alarms ---------- */

function plural(count, word) {
  return `${count} ${word}${count === 1 ? "" : "s"}`;
}

function objectsText(message) {
  const objects = message.objects || [];
  if (objects.length) {
    return objects.map((o) => `#${o.track_id ?? "?"} ${o.box[2]}×${o.box[3]} px at (${o.box[0]}, ${o.box[1]}), `
      + `${Math.round(o.speed_px_s)} px/s`).join(", ");
  }
  return (message.boxes || []).map((b) => `${b[2]}×${b[3]} px at (${b[0]}, ${b[1]})`).join(", ");
}

function alarmKey(cameraId, eventId, ts) {
  return eventId === null || eventId === undefined ? `c${cameraId}@${ts}` : `e${eventId}`;
}

/* "Clear list" hides, across reloads, the events that started up to the newest one the
   page had heard of: a time on the server's clock, as the events' started_at are (the
   browser's clock may be off by minutes or hours). */
const CLEARED_KEY = "vigil.alarmsClearedThrough";

function noteEventTime(ts) {
  if (Number.isFinite(ts) && ts > state.newestEventTs) state.newestEventTs = ts;
}

/* One entry per event: made by its first alarm (or from GET /api/events on page load),
   updated by the next alarms of the event and by its motion_end. */
function alarmItem(key, cameraId, eventId, started) {
  let item = state.alarmItems.get(key);
  if (item) return item;
  item = document.createElement("li");
  if (eventId !== null && eventId !== undefined) item.dataset.event = eventId;
  item.dataset.camera = cameraId;
  item.innerHTML = `<span class="shot"><span class="muted">snapshot not saved</span></span>
    <div><b class="who"></b> — <span class="when"></span> <span class="alarms muted"></span><br>
    <span class="objects"></span><br><span class="ongoing">moving…</span> <span class="links"></span></div>`;
  $(".when", item).textContent = fmtDate(started);
  state.alarmItems.set(key, item);
  return item;
}

function setAlarmPicture(item, snapshot, difference) {
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

/* Snapshots deleted (by this page, or elsewhere as /ws tells): the alarms that showed them
   say so, and the toasts that show them lose the picture (their words say enough). */
function noteDeletedSnapshots(ids) {
  const urls = new Set(ids.map((id) => `/api/snapshots/${id}.jpg`));
  for (const item of state.alarmItems.values()) {
    const shot = $(".shot a", item);
    if (shot && urls.has(shot.getAttribute("href"))) setNoPicture(item, "snapshot deleted");
    const difference = $(".links a", item);
    if (difference && urls.has(difference.getAttribute("href"))) difference.remove();
  }
  for (const img of $$("#toasts img")) if (urls.has(img.getAttribute("src"))) img.remove();
}

function setAlarmEnded(item, durationS, maxArea) {
  const ongoing = $(".ongoing", item);
  ongoing.textContent = `ended after ${durationS.toFixed(1)} s, peak area ${Math.round(maxArea)} px`;
  ongoing.classList.add("ended");
}

function trimAlarmList() {
  const list = $("#alarm-list");
  while (list.children.length > ALARM_LIST_MAX) {
    const last = list.lastElementChild;
    for (const [key, item] of state.alarmItems) if (item === last) state.alarmItems.delete(key);
    last.remove();
  }
}

function onAlarm(message) {
  const name = message.camera_name || cameraName(message.camera_id);
  const count = (message.boxes || []).length;
  const list = state.alarmsAt.get(message.camera_id) || [];
  list.push(message.ts);
  state.alarmsAt.set(message.camera_id, list.slice(-50));
  noteCamera(message.camera_id);
  noteEventTime(message.ts);
  const key = alarmKey(message.camera_id, message.event_id, message.ts);
  const item = alarmItem(key, message.camera_id, message.event_id, message.ts);
  item._alarms = (item._alarms || 0) + 1;
  $(".who", item).textContent = name;
  $(".alarms", item).textContent = item._alarms > 1 ? `(${item._alarms} alarms, last at ${fmtTime(message.ts)})` : "";
  $(".objects", item).textContent = `${plural(count, "object")}: ${objectsText(message)}`;
  // No snapshot when the disk refused it (full, read-only): the event still counts.
  setAlarmPicture(item, message.snapshot, message.difference);
  $("#alarm-list").prepend(item);  // On top: new, or its event moving again.
  trimAlarmList();

  const repeats = item._alarms > 1 ? ` <span class="repeats">×${item._alarms}</span>` : "";
  toast(`<div class="toast-text"><b>Motion on ${escapeHtml(name)}</b>${repeats}<br>${fmtTime(message.ts)} — `
    + `${plural(count, "object")}</div>`
    + (message.snapshot ? `<img src="${message.snapshot}" alt="snapshot">` : ""),
  "alarm", `alarm:${key}`);
  beep();
  const card = state.cards.get(message.camera_id);
  if (card) {
    card.classList.remove("flash");
    void card.offsetWidth;
    card.classList.add("flash");
  }
  scheduleGallery();
}

function onMotionEnd(message) {
  const key = alarmKey(message.camera_id, message.event_id, message.ts);
  const item = state.alarmItems.get(key);
  if (item) setAlarmEnded(item, message.duration_s, message.max_area);
  const shown = findToast(`alarm:${key}`);
  if (shown) shown.classList.add("ended");
  state.closedToasts.delete(`alarm:${key}`);  // The event is over: none of its alarms comes.
}

/* The recent events (the list survived no reload before), with their first snapshots. */
async function loadRecentAlarms() {
  let events;
  try {
    events = await api("GET", "/api/events?limit=500");
  } catch (_) {
    return;  // Shown on the next action; the live alarms still come.
  }
  for (const event of events) {
    noteCamera(event.camera_id);
    noteEventTime(event.started_at);
  }
  renderCameraFilter();
  const clearedThrough = Number(localStorage.getItem(CLEARED_KEY) || 0);
  const recent = events.filter((e) => e.started_at > clearedThrough).slice(0, HISTORY_EVENTS);
  if (!recent.length) return;
  const pictures = new Map();  // event id -> {frame, difference}: its first snapshots
  let listedAll = false;  // Every snapshot since the oldest event: none listed is none kept.
  try {
    const since = Math.min(...recent.map((e) => e.started_at)) - 1;
    const snapshots = await api("GET", `/api/snapshots?since=${since}&limit=${HISTORY_SNAPSHOTS}`);
    listedAll = snapshots.length < HISTORY_SNAPSHOTS;
    for (const snap of snapshots) {
      if (snap.event_id === null || snap.event_id === undefined) continue;
      const entry = pictures.get(snap.event_id) || {};
      entry[snap.kind] = snap.url;  // Newest first: the last one seen is the first taken.
      pictures.set(snap.event_id, entry);
    }
  } catch (_) { /* listed without pictures */ }
  const list = $("#alarm-list");
  for (const event of recent) {  // Newest first, after any alarm that came meanwhile.
    const key = alarmKey(event.camera_id, event.id, event.started_at);
    const shown = state.alarmItems.get(key);
    if (shown) {  // Its end may have come while /ws was away (a restart ends it unsaid).
      if (event.ended_at) setAlarmEnded(shown, event.ended_at - event.started_at, event.max_area);
      continue;
    }
    const item = alarmItem(key, event.camera_id, event.id, event.started_at);
    $(".who", item).textContent = cameraName(event.camera_id);
    $(".objects", item).textContent = `${plural((event.boxes || []).length, "object")}`
      + `${event.boxes && event.boxes.length ? `: ${objectsText(event)}` : ""}`;
    const picture = pictures.get(event.id) || {};
    setAlarmPicture(item, picture.frame, picture.difference);
    // None among all listed: none was saved (a full disk), or it has been deleted since.
    if (!picture.frame && listedAll) {
      setNoPicture(item, "no snapshot", "none was saved, or it has been deleted since");
    }
    if (event.ended_at) setAlarmEnded(item, event.ended_at - event.started_at, event.max_area);
    list.append(item);
  }
  trimAlarmList();
}

$("#clear-alarms").addEventListener("click", () => {
  $("#alarm-list").innerHTML = "";
  state.alarmItems.clear();
  const clearedThrough = Math.max(Number(localStorage.getItem(CLEARED_KEY) || 0), state.newestEventTs);
  if (clearedThrough > 0) localStorage.setItem(CLEARED_KEY, String(clearedThrough));
});

/* ---------- WebSocket ---------- */

let wsDelay = 500;

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const socket = new WebSocket(`${scheme}://${location.host}/ws`);
  const badge = $("#ws-state");
  socket.onopen = () => {
    wsDelay = 500;
    badge.textContent = "live";
    badge.className = "badge badge-live";
    badge.title = "live connection to the server";
    const reconnected = state.wsEverUp;
    state.ws = "up";
    state.wsEverUp = true;
    for (const [id, card] of state.cards) updateCard(card, state.cameras.get(id));
    // Streams that were open when the server went away ended without an error event:
    // open every picture again (a restarted server may also have other cameras).
    if (reconnected) {
      for (const card of state.cards.values()) restartPictures(card);
      loadCameras();
      loadGallery("shown");
      loadRecentAlarms();
    }
  };
  socket.onclose = () => {
    badge.textContent = "server unreachable";
    badge.className = "badge badge-reconnecting";
    badge.title = "no connection to the server: trying again";
    if (state.ws !== "down") {
      state.ws = "down";
      for (const [id, card] of state.cards) updateCard(card, state.cameras.get(id));
    }
    setTimeout(connect, wsDelay);
    wsDelay = Math.min(wsDelay * 2, 5000);
  };
  socket.onmessage = (event) => {
    let message;
    try { message = JSON.parse(event.data); } catch (_) { return; }
    switch (message.type) {
      case "alarm": onAlarm(message); break;
      case "motion_end": onMotionEnd(message); break;
      case "progress": onProgress(message); break;
      case "snapshots_deleted": onSnapshotsDeleted(message.ids); break;
      case "status":
        if (message.camera_id !== undefined) onCameraStatus(message);
        else if (message.analysis_id !== undefined) refreshAnalysis(message.analysis_id);
        break;
      default: break;
    }
  };
}

function onCameraStatus(message) {
  const { type, camera_id: _, storage_error: __, ...fields } = message;
  state.statuses.set(message.camera_id, { at: performance.now(), fields });
  const camera = state.cameras.get(message.camera_id);
  if (!camera) {
    loadCameras();
    return;
  }
  if ("storage_error" in message) {
    toast(message.storage_error
      ? `<b>Snapshots of ${escapeHtml(camera.name)} not saved:</b> ${escapeHtml(message.storage_error)}`
      : `Snapshots of ${escapeHtml(camera.name)} are saved again`, message.storage_error ? "error" : "info");
  }
  Object.assign(camera, fields);
  updateCard(state.cards.get(message.camera_id), camera);
  recordMotion(message.camera_id, Date.now() / 1000, message.motion || 0);
}

/* ---------- Uploads ---------- */

function dismissedAnalyses() {
  try {
    return JSON.parse(localStorage.getItem("vigil.dismissedAnalyses") || "[]");
  } catch (_) {
    return [];
  }
}

function analysisPanel(id, filename) {
  let panel = state.analyses.get(id);
  if (panel) return panel;
  panel = document.createElement("article");
  panel.className = "analysis";
  panel.dataset.id = id;
  panel.innerHTML = `<header><b class="file"></b> <span class="badge status">queued</span>
    <button type="button" class="cancel" hidden>Cancel upload</button>
    <button type="button" class="dismiss" title="remove this panel (the analysis stays on the server)"
      aria-label="dismiss" hidden>✕</button></header>
    <label>Upload <progress class="upload-bar" max="1" value="1"></progress></label>
    <label>Analysis <progress class="analysis-bar" max="1" value="0"></progress> <span class="pct"></span></label>
    <div class="live-view"></div><p class="error"></p><div class="result"></div>`;
  $(".file", panel).textContent = filename || id;
  $(".dismiss", panel).addEventListener("click", () => {
    const key = panel.dataset.id;
    if (!key.startsWith("upload-")) {
      const dismissed = dismissedAnalyses().filter((d) => d !== key);
      dismissed.push(key);
      localStorage.setItem("vigil.dismissedAnalyses", JSON.stringify(dismissed.slice(-200)));
    }
    state.analyses.delete(panel.dataset.id);
    panel.remove();
    assignPictureModes();
  });
  $("#analyses").prepend(panel);
  state.analyses.set(id, panel);
  return panel;
}

$("#upload").addEventListener("submit", (event) => {
  event.preventDefault();
  const form = event.target;
  const file = form.file.files[0];
  if (!file) return;
  const data = new FormData();
  data.append("file", file);
  data.append("method", form.method.value);
  if (form.sensitivity.value) data.append("sensitivity", form.sensitivity.value);
  if (form.min_area.value) data.append("min_area", form.min_area.value);
  const pending = analysisPanel(`upload-${Date.now()}`, file.name);
  const bar = $(".upload-bar", pending);
  bar.value = 0;
  $(".status", pending).textContent = "uploading";
  const xhr = new XMLHttpRequest();
  xhr.open("POST", "/api/analyses");
  xhr.upload.onprogress = (e) => { if (e.lengthComputable) bar.value = e.loaded / e.total; };
  const cancel = $(".cancel", pending);
  cancel.hidden = false;
  // Sent whole, the video is the server's to analyse: nothing is left to cancel.
  xhr.upload.onload = () => { cancel.hidden = true; };
  cancel.onclick = () => xhr.abort();
  state.uploads.add(xhr);
  xhr.onloadend = () => {
    state.uploads.delete(xhr);
    cancel.hidden = true;
  };
  xhr.onabort = () => {
    setStatus(pending, null, "cancelled");
    $(".error", pending).textContent = "Upload cancelled: the video was not sent.";
  };
  xhr.onload = () => {
    if (xhr.status === 401) {
      toLogin();
      return;
    }
    let body = {};
    try { body = JSON.parse(xhr.responseText); } catch (_) { /* not JSON */ }
    if (xhr.status !== 202) {
      setStatus(pending, null, "failed");
      $(".error", pending).textContent = typeof body.detail === "string" ? body.detail : `upload failed (${xhr.status})`;
      return;
    }
    bar.value = 1;
    state.analyses.delete(pending.dataset.id);
    state.analyses.set(body.id, pending);
    pending.dataset.id = body.id;
    refreshAnalysis(body.id);
    form.reset();
  };
  xhr.onerror = () => {
    setStatus(pending, null, "failed");
    $(".error", pending).textContent = "the upload was interrupted";
  };
  xhr.send(data);
});

/* Leaving the page (reload, close, another address) ends an upload under way: the
   browser asks first. */
window.addEventListener("beforeunload", (event) => {
  if (!state.uploads.size) return;
  event.preventDefault();
  event.returnValue = "";  // What older browsers ask for.
});

function onProgress(message) {
  const panel = state.analyses.get(message.analysis_id);
  if (!panel) {
    refreshAnalysis(message.analysis_id);
    return;
  }
  $(".analysis-bar", panel).value = message.progress;
  $(".pct", panel).textContent = `${Math.round(message.progress * 100)} %`;
  if ($(".status", panel).textContent === "queued") setStatus(panel, message.analysis_id, "running");
}

function setStatus(panel, id, status) {
  const badge = $(".status", panel);
  badge.textContent = status;
  badge.className = `badge status badge-${status}`;
  $(".dismiss", panel).hidden = !["done", "failed", "cancelled"].includes(status);
  const view = $(".live-view", panel);
  if (status === "running" && !$("img", view)) {
    // A live stream holds a connection: one camera fewer streams meanwhile.
    view.innerHTML = `<img class="streaming" alt="analysis in progress" data-stream="/api/analyses/${id}/stream.mjpg">`;
    showAnalysisStreams();
    assignPictureModes();
  }
}

/* The streams of the analyses watched live: open while the page is shown, closed while
   it is hidden (each still counts against STREAM_BUDGET: it comes back when shown). */
function showAnalysisStreams() {
  for (const img of $$("#analyses .live-view img.streaming")) {
    if (document.hidden) img.removeAttribute("src");
    else if (!img.getAttribute("src")) img.src = img.dataset.stream;
  }
}

async function refreshAnalysis(id) {
  let analysis;
  try {
    analysis = await api("GET", `/api/analyses/${id}`);
  } catch (_) {
    return;
  }
  const panel = analysisPanel(id, analysis.filename);
  setStatus(panel, id, analysis.status);
  $(".analysis-bar", panel).value = analysis.progress;
  $(".pct", panel).textContent = `${Math.round(analysis.progress * 100)} %`;
  $(".error", panel).textContent = analysis.error || "";
  if (analysis.status === "done" && !panel.dataset.rendered) {
    panel.dataset.rendered = "1";
    renderResult(panel, analysis);
  }
  if (analysis.status === "failed") $(".live-view", panel).innerHTML = "";
  if (analysis.status === "done" || analysis.status === "failed") assignPictureModes();
}

function fixed(value, digits) {
  return value === null || value === undefined || value === "" || !Number.isFinite(Number(value))
    ? "" : Number(value).toFixed(digits);
}

function renderResult(panel, analysis) {
  const links = analysis.links;
  const report = analysis.report || {};
  const tracks = report.tracks || [];
  // Metres and km/h only with a calibrated camera: otherwise the columns stay out.
  const calibrated = tracks.some((t) => (t.distance_m ?? null) !== null || (t.mean_speed_km_h ?? null) !== null);
  const rows = tracks.map((t) => `<tr><td>#${t.track_id}</td><td>${t.first_frame}–${t.last_frame}</td>
    <td>${fixed(t.duration_s, 2)}</td><td>${fixed(t.distance_px, 1)}</td><td>${fixed(t.mean_speed_px_s, 1)}</td>
    <td>${fixed(t.max_speed_px_s, 1)}</td>${calibrated
      ? `<td>${fixed(t.distance_m, 2)}</td><td>${fixed(t.mean_speed_km_h, 1)}</td>` : ""}</tr>`).join("");
  const columns = calibrated ? 8 : 6;
  const events = report.events ?? 0;
  // What the input did not give whole (frames that did not decode, an early end), or
  // what the settings cannot find: said on the page as the report says it.
  const warnings = (report.warnings || []).map((w) => `<li>${escapeHtml(w)}</li>`).join("");
  $(".live-view", panel).innerHTML = `<img alt="last analysed frame" src="${links.stream}?end=1">`;
  $(".result", panel).innerHTML = `
    <p>${report.frames ?? "?"} frames at ${report.fps ?? "?"} fps, ${plural(events, "event")},
      ${plural(tracks.length, "tracked object")}, method ${escapeHtml(report.method ?? "")}.</p>
    ${warnings ? `<ul class="warnings">${warnings}</ul>` : ""}
    <p class="links"><a href="${links.annotated}">annotated.avi</a> · <a href="${links.tracks}">tracks.csv</a> ·
      <a href="${links.report_html}" target="_blank">report</a> · <a href="${links.report}" target="_blank">report.json</a></p>
    <div class="table-wrap"><table class="tracks"><thead><tr><th>track</th><th>frames</th><th>duration s</th>
      <th>distance px</th><th>mean px/s</th><th>max px/s</th>${calibrated ? "<th>distance m</th><th>km/h</th>" : ""}
      </tr></thead><tbody>${rows
      || `<tr><td colspan="${columns}">no moving objects found</td></tr>`}</tbody></table></div>`;
}

async function loadAnalyses() {
  try {
    const dismissed = new Set(dismissedAnalyses());
    const analyses = (await api("GET", "/api/analyses")).filter((a) => !dismissed.has(a.id)).slice(0, 10);
    // Panels made now, oldest first (each goes on top), so the newest stays on top
    // whatever order their details arrive in.
    for (const analysis of analyses.slice().reverse()) analysisPanel(analysis.id, analysis.filename);
    for (const analysis of analyses) refreshAnalysis(analysis.id);
  } catch (_) { /* shown on the next action */ }
}

/* ---------- Snapshot gallery ---------- */

/* A camera id seen in an event or a snapshot: a deleted camera's stay in the gallery filter. */
function noteCamera(id) {
  if (id === null || id === undefined || state.knownCameraIds.has(id)) return;
  state.knownCameraIds.add(id);
  if (state.camerasLoaded && !state.cameras.has(id)) renderCameraFilter();
}

function renderCameraFilter() {
  const select = $("#gallery-filter select[name=camera_id]");
  const current = select.value;
  const deleted = Array.from(state.knownCameraIds).filter((id) => !state.cameras.has(id)).sort((a, b) => a - b);
  select.innerHTML = '<option value="">all</option>' + Array.from(state.cameras.values())
    .map((c) => `<option value="${c.id}">${escapeHtml(c.name)}</option>`).join("")
    + (state.camerasLoaded ? deleted.map((id) => `<option value="${id}">${escapeHtml(cameraName(id))}</option>`).join("") : "");
  select.value = current;
  if (select.value !== current) select.value = "";
}

function galleryQuery() {
  const form = $("#gallery-filter");
  const params = new URLSearchParams();
  if (form.camera_id.value) params.set("camera_id", form.camera_id.value);
  if (form.kind.value) params.set("kind", form.kind.value);
  if (form.since.value) params.set("since", String(new Date(form.since.value).getTime() / 1000));
  if (form.until.value) params.set("until", String(new Date(form.until.value).getTime() / 1000));
  return params;
}

/* The gallery shows a run of the listing (newest first, by time then id): from the newest
   snapshot its filters match down to the oldest shown; "Show older" adds the next page.
   A snapshot is a cursor into the listing, its time and id (the API's until/until_id and
   since/since_id), so snapshots that share a time at a page's edge are neither skipped
   nor shown twice; and "Download all shown" asks for the run shown, ends included. */
function endAt(params, end, snap, id = snap.id) {
  params.set(end, String(snap.ts));
  params.set(`${end}_id`, String(id));
}

/* Asks for a listing; its snapshots, or null where it failed (said in a toast). */
async function listGallery(params) {
  try {
    return await api("GET", `/api/snapshots?${params}`);
  } catch (error) {
    toast(`Cannot load snapshots: ${escapeHtml(error.message)}`, "error");
    return null;
  }
}

/* Runs a gallery listing after those asked for before it: an alarm's refresh and "Show
   older" each build on what the other showed, and neither answer is lost. */
function queueGallery(task) {
  const run = state.gallery.queue.then(task);
  state.gallery.queue = run.catch(() => {});
  return run;
}

/* How the gallery is listed again:
   - "fresh": from the newest, with the filters of the form (new filters, the page opened);
   - "shown": the same filters, as far down as shown, with what came in since on top (the
     server back: snapshots may have been deleted or pruned meanwhile);
   - "newer": only what came in after the newest shown, put on top (an alarm: listing again
     all that is shown, up to GALLERY_MAX, would be a large request for each alarm).
   One refresh waiting for its turn stands for any asked meanwhile ("shown" for "newer"). */
function loadGallery(how = "newer") {
  const gallery = state.gallery;
  if (how !== "fresh") {
    if (gallery.waiting) {
      if (how === "shown") gallery.waiting = how;
      return gallery.queue;
    }
    gallery.waiting = how;
  }
  return queueGallery(() => {
    if (how === "fresh") return refreshGallery(true);
    const waited = gallery.waiting;
    gallery.waiting = null;
    return waited === "newer" ? listNewer() : refreshGallery(false);
  });
}

async function refreshGallery(fresh) {
  const gallery = state.gallery;
  if (fresh || !gallery.filters) gallery.filters = galleryQuery();
  const params = new URLSearchParams(gallery.filters);
  const shown = fresh ? [] : gallery.snapshots;
  // Older ones are not shown: stay down to the oldest shown (deleted since, it still counts).
  const down = !fresh && gallery.more && gallery.oldest !== null;
  if (down) endAt(params, "since", gallery.oldest);
  const limit = Math.min(GALLERY_MAX, shown.length + GALLERY_PAGE);
  params.set("limit", String(limit + 1));  // One more tells whether there are more.
  const snapshots = await listGallery(params);
  if (!snapshots) return;
  const cut = snapshots.length > limit;  // So many came in that the oldest shown fall off.
  gallery.snapshots = snapshots.slice(0, limit);
  gallery.gone.clear();  // Listed as the server has them: none deleted among them.
  if (cut || !down) gallery.oldest = gallery.snapshots.at(-1) || null;
  gallery.more = down || cut;
  renderGallery();
}

/* The snapshots taken after the newest shown (its time, then the ids after it: the
   listing's cursor), on top of those shown. */
async function listNewer() {
  const gallery = state.gallery;
  const newest = gallery.snapshots[0];
  if (!newest) return refreshGallery(false);
  const params = new URLSearchParams(gallery.filters);
  endAt(params, "since", newest, newest.id + 1);
  params.set("limit", String(GALLERY_PAGE + 1));  // One more tells whether some were left out.
  const newer = await listGallery(params);
  if (!newer) return;
  // More than a page at once: those left out would be a hole below them. As far down as shown.
  if (newer.length > GALLERY_PAGE) return refreshGallery(false);
  const shown = new Set(gallery.snapshots.map((s) => s.id));
  const added = newer.filter((s) => !shown.has(s.id));
  if (!added.length) return;
  const snapshots = added.concat(gallery.snapshots);
  gallery.snapshots = snapshots.slice(0, GALLERY_MAX);
  if (snapshots.length > GALLERY_MAX) {  // The oldest shown fall off.
    gallery.oldest = gallery.snapshots.at(-1);
    gallery.more = true;
  }
  renderGallery();
}

function showOlder() {
  const button = $("#gallery-more");
  button.disabled = true;
  return queueGallery(showOlderPage).finally(() => { button.disabled = false; });
}

async function showOlderPage() {
  const gallery = state.gallery;
  const room = Math.min(GALLERY_PAGE, GALLERY_MAX - gallery.snapshots.length);
  if (gallery.oldest === null || room <= 0) return;
  const params = new URLSearchParams(gallery.filters);
  endAt(params, "until", gallery.oldest, gallery.oldest.id - 1);
  params.set("limit", String(room + 1));
  const older = await listGallery(params);
  if (!older) return;
  const page = older.slice(0, room);
  gallery.snapshots = gallery.snapshots.concat(page);
  if (page.length) gallery.oldest = page.at(-1);
  gallery.more = older.length > room;
  renderGallery();
}

const GONE_NOTE = '<div class="gone-note">snapshot deleted</div>';

function thumbHtml(snap, selected) {
  const gone = state.gallery.gone.has(snap.id);
  const picture = gone ? GONE_NOTE : `<label><input type="checkbox" value="${snap.id}" ${selected ? "checked" : ""}>
      <img loading="lazy" src="${snap.url}" alt="snapshot ${snap.id}"></label>`;
  return `<figure class="thumb${gone ? " gone" : ""}" data-id="${snap.id}">${picture}
      <figcaption>${escapeHtml(cameraName(snap.camera_id))} · ${fmtDate(snap.ts)} · ${snap.kind}</figcaption>
    </figure>`;
}

function renderGallery() {
  const { snapshots, more } = state.gallery;
  for (const snap of snapshots) noteCamera(snap.camera_id);
  const selected = new Set($$("#thumbs input:checked").map((i) => i.value));
  $("#thumbs").innerHTML = snapshots.map((s) => thumbHtml(s, selected.has(String(s.id)))).join("")
    || `<p class="muted">${more ? "None left here: older ones are below." : "No snapshots yet: Activate a camera."}</p>`;
  renderGalleryTotals();
}

/* The count, "Show older" and "Download all shown": of the snapshots shown, those not
   deleted elsewhere (the zip asks for the run from the newest to the oldest of them). */
function renderGalleryTotals() {
  const { snapshots, more, filters, gone } = state.gallery;
  const kept = snapshots.filter((s) => !gone.has(s.id));
  const full = snapshots.length >= GALLERY_MAX;  // As many as a page holds: no more below.
  $("#gallery-more").hidden = !more || full;
  $("#gallery-count").textContent = !snapshots.length ? ""
    : `${plural(kept.length, "snapshot")} shown, newest first`
      + `${!more ? "" : full ? ": for older ones, filter by time" : ", older ones below"}`;
  const zip = $("#zip-all");
  const params = new URLSearchParams(filters);
  if (kept.length) {
    endAt(params, "until", kept[0]);
    endAt(params, "since", kept[kept.length - 1]);
    params.set("limit", String(kept.length));
  }
  zip.href = kept.length ? `/api/snapshots.zip?${params}` : "#";
  zip.classList.toggle("disabled", !kept.length);
  zip.textContent = `Download all ${kept.length} shown (.zip)`;
  updateZipSelected();
}

/* A snapshot's picture that does not load (in the gallery, the alarm list or a toast)
   shows no broken-picture icon. The server, asked again, tells whether the snapshot has
   been deleted meanwhile (by another tab, a bulk delete, pruning); then the place says so,
   and the gallery's tile stays, greyed, out of the selection and the zips. Any other
   failure (the server unreachable) leaves the place blank until it is drawn again. */
document.addEventListener("error", async (event) => {
  const img = event.target;
  if (!(img instanceof HTMLImageElement) || !img.closest("#thumbs, #alarm-list, #toasts")) return;
  img.classList.add("broken");
  const url = img.getAttribute("src");
  const id = Number(/^\/api\/snapshots\/(\d+)\.jpg$/.exec(url)?.[1]);
  if (id && await snapshotDeleted(url)) onSnapshotsDeleted([id]);  // As /ws would tell.
}, true);  // An error event does not bubble: caught on its way down.

async function snapshotDeleted(url) {
  try {
    return (await fetch(url, { cache: "no-store" })).status === 404;
  } catch (_) {
    return false;
  }
}

/* Greys the tiles of those snapshots shown that have been deleted elsewhere: in place, so
   no tile moves under the pointer, but out of the count, the selection and the zips. */
function markGone(ids) {
  const { snapshots, gone } = state.gallery;
  const deleted = new Set(ids);
  const shown = snapshots.filter((s) => deleted.has(s.id) && !gone.has(s.id));
  if (!shown.length) return;
  for (const { id } of shown) {
    gone.add(id);
    const tile = $(`#thumbs .thumb[data-id="${id}"]`);  // The gallery may have been drawn again.
    if (!tile) continue;
    tile.classList.add("gone");
    const label = $("label", tile);  // With its checkbox: no longer to select.
    if (label) label.outerHTML = GONE_NOTE;
  }
  renderGalleryTotals();
}

/* Snapshots deleted on the server, by any page or by pruning: none shows here any more,
   even one whose picture the browser has already loaded. The gallery's after any listing
   under way, which may have been answered before they went. */
function onSnapshotsDeleted(ids) {
  noteDeletedSnapshots(ids);
  queueGallery(() => markGone(ids));
}

let galleryTimer = null;
function scheduleGallery() {
  clearTimeout(galleryTimer);
  galleryTimer = setTimeout(() => loadGallery("newer"), 1000);
}

function selectedIds() {
  return $$("#thumbs input:checked").map((i) => Number(i.value));
}

function updateZipSelected() {
  const ids = selectedIds();
  const link = $("#zip-selected");
  link.href = ids.length ? `/api/snapshots.zip?ids=${ids.join(",")}` : "#";
  link.classList.toggle("disabled", !ids.length);
  // "select all" says what is ticked: a snapshot that arrives after it was ticked comes
  // unticked (the user has not seen it to delete it), and so unticks it.
  const shown = $$("#thumbs input").length;
  $("#select-all").checked = shown > 0 && ids.length === shown;
}

$("#thumbs").addEventListener("change", updateZipSelected);
$("#select-all").addEventListener("change", (e) => {
  for (const box of $$("#thumbs input")) box.checked = e.target.checked;
  updateZipSelected();
});
$("#zip-selected").addEventListener("click", (e) => { if (!selectedIds().length) e.preventDefault(); });
$("#zip-all").addEventListener("click", (e) => { if (e.currentTarget.classList.contains("disabled")) e.preventDefault(); });
$("#gallery-more").addEventListener("click", showOlder);
$("#delete-selected").addEventListener("click", async () => {
  const ids = selectedIds();
  if (!ids.length || !confirm(`Delete ${ids.length} snapshot(s)?`)) return;
  try {
    noteDeletedSnapshots((await api("POST", "/api/snapshots/delete", { ids })).deleted);
  } catch (error) {
    toast(escapeHtml(error.message), "error");
    return;
  }
  // Off the gallery, all of them: those the server did not delete now were gone already.
  // After any listing under way, which may still have them.
  const deleted = new Set(ids);
  $("#select-all").checked = false;
  queueGallery(() => {
    state.gallery.snapshots = state.gallery.snapshots.filter((s) => !deleted.has(s.id));
    renderGallery();
  });
});
$("#gallery-filter").addEventListener("submit", (e) => { e.preventDefault(); loadGallery("fresh"); });

/* ---------- Start ---------- */

renderMute();
loadCameras().then(() => {
  loadGallery("fresh");
  loadRecentAlarms();
});
loadAnalyses();
connect();
setInterval(() => { if (state.ws !== "down") loadCameras(); }, 15000);
setInterval(() => { for (const id of state.cameras.keys()) drawMotion(id, Date.now() / 1000); }, 1000);
setInterval(watchStreams, 2000);
