/* A camera card's pictures: the live picture, drawn from /ws/live while the card is on
   screen (LiveFrames says which cameras are watched), and the grey-level histogram,
   polled once a second while it is shown. */
import { $ } from "../lib/dom.js";
import { sendsPictures } from "../api/cameras.js";
import { LivePicture } from "./live-picture.js";

const HISTOGRAM_MS = 1000;
const SHOWN_WINDOW_MS = 5000;  // "shown/s" counts the frames drawn over this long.

export class CameraPictures {
  /* onSize(): the picture's frame size changed (the first frame, a new source). */
  constructor(card, id, { cameras, connection, liveFrames, onSize }) {
    this.card = card;
    this.id = id;
    this.cameras = cameras;
    this.connection = connection;
    this.liveFrames = liveFrames;
    this.histogram = $(".histogram", card);
    this.shownAt = [];
    let size = "";
    this.live = new LivePicture($(".live", card), (header) => {
      this.shownAt.push(performance.now());
      if (this.shownAt.length > 200) this.shownAt.splice(0, 100);
      if (card.classList.contains("no-picture")) card.classList.remove("no-picture");
      if (String(header.size) !== size) {
        size = String(header.size);
        onSize();
      }
    });
    liveFrames.add(id, this.live, $(".picture", card));
    this.started = false;  // the histogram's polling, once the camera has been live
    this.loop = null;
  }

  /* Whether the histogram may be asked for now: not while the server is unreachable, the
     camera is down (the answer would be a 503), or the histogram is off screen. */
  canFetch() {
    const camera = this.cameras.get(this.id);
    return this.connection.state !== "down" && Boolean(camera) && sendsPictures(camera)
      && this.liveFrames.watched(this.id) && this.histogram.checkVisibility();
  }

  start() {
    this.started = true;
    const img = this.histogram;
    const loop = { timer: null, stopped: false };
    const go = () => {
      if (loop.stopped) return;
      if (!this.canFetch()) {
        loop.timer = setTimeout(go, 500);
        return;
      }
      img.src = `/api/cameras/${this.id}/histogram.jpg?t=${Date.now()}`;
    };
    img.onload = () => {
      img.classList.remove("broken");
      if (!loop.stopped) loop.timer = setTimeout(go, HISTOGRAM_MS);
    };
    img.onerror = () => {
      img.classList.add("broken");  // No broken-image icon: the last picture or nothing.
      if (!loop.stopped) loop.timer = setTimeout(go, HISTOGRAM_MS);
    };
    this.loop = loop;
    go();
  }

  stop() {
    if (this.loop) {
      this.loop.stopped = true;
      clearTimeout(this.loop.timer);
    }
    this.histogram.onload = null;
    this.histogram.onerror = null;
  }

  /* A new source: the old one's last picture goes (the first frame of the new one is drawn
     as it comes; the server follows the camera to its new worker by itself). */
  restart() {
    this.live.clear();
    this.card.classList.add("no-picture");
  }

  remove() {
    this.stop();
    this.liveFrames.remove(this.id);
  }

  /* The camera's frame rate, and how many frames a second were drawn here (last 5 s). */
  fpsText(camera) {
    const fps = `${(camera.fps || 0).toFixed(1)} fps`;
    if (!this.liveFrames.watched(this.id)) return fps;
    const now = performance.now();
    const shown = this.shownAt.filter((t) => t > now - SHOWN_WINDOW_MS).length;
    return `${fps} · ${(shown / (SHOWN_WINDOW_MS / 1000)).toFixed(1)} shown/s`;
  }
}
