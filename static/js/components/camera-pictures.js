/* A camera card's pictures: the live picture, an MJPEG stream or polled single frames (as
   the grid decides), and the grey-level histogram, polled. */
import { $ } from "../lib/dom.js";
import { sendsPictures } from "../api/cameras.js";

/* A polled picture asks for the next frame as soon as the last has loaded (the server
   answers when the camera has a new one), at most MAX_POLL_FPS a second. */
const MAX_POLL_FPS = 30;
const HISTOGRAM_MS = 1000;
/* An MJPEG <img> fires no event when its stream ends or stalls: it just keeps the last
   picture. Every few seconds the picture of each streamed live camera is sampled; one
   that has not changed for STALL_MS is reopened. (A camera that sends the very same
   picture for that long is reopened too, which costs one request.) */
const STALL_MS = 10000;

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

/* No picture, and no connection held for one, until the next src. */
function blankPicture(img) {
  img.removeAttribute("src");
  img.classList.add("broken");
}

export class CameraPictures {
  constructor(card, id, cameras, connection) {
    this.card = card;
    this.live = $(".live", card);
    this.histogram = $(".histogram", card);
    this.id = id;
    this.cameras = cameras;
    this.connection = connection;
    this.mode = null;      // "stream" or "poll", as the grid assigns
    this.started = false;  // once the camera has been live; they carry on across reconnects
    this.timers = [];      // retries of a failed stream
    this.loops = [];       // the polls under way
    this.still = null;     // the stall watcher's {hash, since}: the picture seen unchanged
    this.shownAt = [];     // when the last polled frames were shown, for "shown/s"
  }

  setMode(mode) {
    if (this.mode === mode) return;
    this.mode = mode;
    this.card.classList.toggle("polled", mode === "poll");
    if (this.started) this.restart(true);
  }

  /* Whether a polled picture may be asked for now: not while the server is unreachable,
     the camera is down (the answer would be a 503) or the page is hidden. */
  canFetch() {
    const camera = this.cameras.get(this.id);
    return this.connection.state !== "down" && !document.hidden && Boolean(camera) && sendsPictures(camera);
  }

  start() {
    this.timers = [];
    this.loops = [];
    this.started = true;
    this.still = null;
    const img = this.live;
    if (this.mode === "poll") {
      const minMs = () => 1000 / Math.min(MAX_POLL_FPS, Math.max(1, this.cameras.get(this.id)?.fps || 0));
      this.loops.push(this.poll(img, `/api/cameras/${this.id}/frame.jpg`, minMs, () => {
        this.shownAt.push(performance.now());
      }));
    } else if (document.hidden) {
      blankPicture(img);  // A hidden page holds no stream (see "visibilitychange").
    } else {
      img.onload = () => img.classList.remove("broken");
      img.onerror = () => {
        img.classList.add("broken");
        // While the server is away the /ws reconnect reopens every picture.
        if (this.connection.state !== "down") this.timers.push(setTimeout(() => this.restart(), 2000));
      };
      img.src = `/api/cameras/${this.id}/stream.mjpg?r=${Date.now()}`;
    }
    this.loops.push(this.poll(this.histogram, `/api/cameras/${this.id}/histogram.jpg`, () => HISTOGRAM_MS));
  }

  /* Asks for the next picture as soon as the last one has loaded, no sooner than every
     minMs() milliseconds; waits without asking while canFetch says no. */
  poll(img, url, minMs, onFrame = null) {
    const loop = { timer: null, started: 0, stopped: false };
    const go = () => {
      if (loop.stopped) return;
      if (!this.canFetch()) {
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
  stop(keep = false) {
    for (const timer of this.timers) clearTimeout(timer);
    for (const loop of this.loops) {
      loop.stopped = true;
      clearTimeout(loop.timer);
    }
    this.timers = [];
    this.loops = [];
    for (const img of [this.live, this.histogram]) {
      img.onload = null;
      img.onerror = null;
      if (!keep) img.removeAttribute("src");
    }
  }

  /* modeChanged: the picture goes from a stream to polled frames or back. The old src
     goes at once: a polled picture is asked for only when canFetch allows (not while the
     page is hidden or the server unreachable), and until then the old src would hold its
     MJPEG connection open. Nothing is shown (no alt text) until the first new picture. */
  restart(modeChanged = false) {
    if (!this.started) return;
    this.stop(true);
    if (modeChanged) blankPicture(this.live);
    this.start();
  }

  /* The frame rate; for polled pictures also how many a second were shown (last 5 s). */
  fpsText(camera) {
    const fps = `${(camera.fps || 0).toFixed(1)} fps`;
    if (this.mode !== "poll") return fps;
    const now = performance.now();
    this.shownAt = this.shownAt.filter((t) => t > now - 5000);
    return `${fps} · ${(this.shownAt.length / 5).toFixed(1)} shown/s`;
  }

  /* The stall watcher's look at a streamed picture (now: Date.now()). */
  checkStall(now) {
    const camera = this.cameras.get(this.id);
    const img = this.live;
    if (!this.started || this.mode === "poll" || this.connection.state !== "up" || document.hidden
        || !camera || camera.state !== "live" || !(camera.fps >= 1) || !img.naturalWidth) {
      this.still = null;
      return;
    }
    const hash = pictureHash(img);
    if (hash === null) return;
    if (!this.still || this.still.hash !== hash) this.still = { hash, since: now };
    else if (now - this.still.since >= STALL_MS) this.restart();
  }
}
