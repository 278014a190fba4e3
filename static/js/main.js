/* Vigil's dashboard: native ES modules, no build step. Makes each part of the page, wires
   them together and to /ws, then starts. The parts talk to /api/* themselves. */
import { Cameras } from "./api/cameras.js";
import { LiveFrames } from "./api/live-frames.js";
import { ServerSocket } from "./api/socket.js";
import { snapshotDeleted, snapshotIdOf, snapshotUrl } from "./api/snapshots.js";
import { CameraFilter } from "./components/camera-filter.js";
import { MqttBadge } from "./components/mqtt-badge.js";
import { AlarmSound } from "./components/sound.js";
import { Toasts } from "./components/toasts.js";
import { Wall } from "./components/wall.js";
import { $ } from "./lib/dom.js";
import { AlarmList, alarmToastHtml } from "./views/alarm-list.js";
import { Analyses } from "./views/analyses.js";
import { CameraGrid } from "./views/camera-grid.js";
import { EventsView } from "./views/events.js";
import { Gallery } from "./views/gallery.js";
import { Notifications } from "./views/notifications.js";

const CAMERA_LISTING_MS = 15000;  // Cameras added or deleted elsewhere show without /ws.
const CHART_MS = 1000;

/* The sticky header's height, for the sections' scroll-margin-top: a nav link brings its
   section's heading just below the header, not under it (it wraps on narrow screens). */
new ResizeObserver(() => {
  document.documentElement.style.setProperty("--top-height", `${$(".top").offsetHeight}px`);
}).observe($(".top"));

const toasts = new Toasts($("#toasts"), $("#toasts-more"));
const sound = new AlarmSound($("#mute"));
const cameras = new Cameras();
const liveFrames = new LiveFrames();
const mqttBadge = new MqttBadge($("#mqtt-state"));
const cameraFilter = new CameraFilter($("#gallery-filter select[name=camera_id]"), cameras);
const eventsFilter = new CameraFilter($("#events-filter select[name=camera_id]"), cameras);
const socket = new ServerSocket($("#ws-state"), {
  opened(reconnected) {
    grid.updateAll();
    // A restarted server may have other cameras (/ws/live reconnects by itself).
    if (reconnected) {
      mqttBadge.refresh();
      grid.load();
      gallery.load("shown");
      alarms.loadRecent();
      events.load();
    }
  },
  closed: () => grid.updateAll(),
  handlers: {
    alarm: onAlarm,
    motion_end: (message) => {
      toasts.ended(`alarm:${alarms.end(message)}`);
      events.heard();
    },
    progress: (message) => analyses.onProgress(message),
    snapshots_deleted: (message) => onSnapshotsDeleted(message.ids),
    camera_status: (message) => grid.onStatus(message),
    analysis_status: (message) => analyses.refresh(message.analysis_id),
  },
});
const grid = new CameraGrid({
  grid: $("#grid"),
  template: $("#camera-card"),
  addForm: $("#add-camera"),
  cameras,
  connection: socket,
  liveFrames,
  toasts,
  listed: () => {
    cameraFilter.render();
    eventsFilter.render();
    notifications.camerasChanged();
    wall.layout();
  },
});
const wall = new Wall($("#wall"), $("#grid"));
const alarms = new AlarmList($("#alarm-list"), $("#clear-alarms"), {
  cameraName: (id) => cameras.name(id),
  noteCamera: (id) => cameraFilter.note(id),
  camerasNoted: () => cameraFilter.render(),
});
const analyses = new Analyses($("#analyses"), $("#upload"));
const events = new EventsView($("#events"), { cameras, toasts });
const notifications = new Notifications($("#notifications"), cameras);
const gallery = new Gallery($("#gallery"), {
  cameraName: (id) => cameras.name(id),
  noteCamera: (id) => cameraFilter.note(id),
  deleted: dropSnapshots,
  toasts,
});

function onAlarm(message) {
  const name = message.camera_name || cameras.name(message.camera_id);
  cameraFilter.note(message.camera_id);
  const { key, count } = alarms.add(message, name);
  toasts.show(alarmToastHtml(message, name, count), "alarm", `alarm:${key}`);
  sound.beep();
  grid.onAlarm(message.camera_id, message.ts);
  gallery.scheduleRefresh();
  events.heard();
  notifications.soon();
}

/* "Play" on an alarm's toast or in the alarm list: its event in the Events section. */
document.addEventListener("click", (event) => {
  const link = event.target.closest?.(".open-event");
  if (!link) return;
  event.preventDefault();
  events.open(Number(link.dataset.event));
});

/* Snapshots deleted (by this page, or elsewhere as /ws tells): the alarms that showed them
   say so, and the toasts that show them lose the picture (their words say enough). */
function dropSnapshots(ids) {
  const urls = new Set(ids.map(snapshotUrl));
  alarms.dropSnapshots(urls);
  toasts.dropPictures(urls);
}

/* Snapshots deleted on the server, by any page or by pruning: none shows here any more,
   even one whose picture the browser has already loaded. */
function onSnapshotsDeleted(ids) {
  dropSnapshots(ids);
  gallery.markGone(ids);
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
  const id = snapshotIdOf(url);
  if (id && await snapshotDeleted(url)) onSnapshotsDeleted([id]);  // As /ws would tell.
}, true);  // An error event does not bubble: caught on its way down.

/* A tab in the background keeps its connections: a forgotten one with an analysis's
   stream open leaves fewer for a new tab of the dashboard. A hidden page closes it and
   opens it again when shown (and watches no camera on /ws/live: LiveFrames). */
document.addEventListener("visibilitychange", () => analyses.showStreams());

grid.load().then(() => {
  gallery.load("fresh");
  alarms.loadRecent();
  events.load();
});
analyses.load();
mqttBadge.start();
notifications.load();
socket.connect();
liveFrames.connect();
setInterval(() => { if (socket.state !== "down") grid.load(); }, CAMERA_LISTING_MS);
setInterval(() => grid.drawCharts(Date.now() / 1000), CHART_MS);
