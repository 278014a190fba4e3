/* /ws/live: the pictures of the cameras on screen, over one WebSocket for the whole page.
   The page says which cameras it shows and how wide ({"type": "watch", "cameras": [ids],
   "width": N}, again whenever that changes); the server sends one binary message per
   frame and camera: a 4-byte big-endian header length, a JSON header (camera_id, frame,
   ts, size, detections, mask), then the JPEG. A camera off screen, or every camera while
   the page is hidden, is not watched: no frames come for it. The socket is made again
   when it drops (after 0.5 s, doubling up to 5 s), as /ws is. */

const FIRST_RETRY_MS = 500;
const LAST_RETRY_MS = 5000;
/* The width asked for, in device pixels, is rounded up to a step: resizing the window
   sends a new watch message only now and then. */
const WIDTH_STEP = 160;

const decoder = new TextDecoder();

/* A message's header and JPEG (a view of the message's bytes); null if malformed. */
export function parseLiveMessage(buffer) {
  if (!(buffer instanceof ArrayBuffer) || buffer.byteLength < 4) return null;
  const length = new DataView(buffer).getUint32(0);  // big-endian
  if (4 + length > buffer.byteLength) return null;
  try {
    const header = JSON.parse(decoder.decode(new Uint8Array(buffer, 4, length)));
    return { header, jpeg: new Uint8Array(buffer, 4 + length) };
  } catch (_) {
    return null;
  }
}

export class LiveFrames {
  constructor() {
    this.cameras = new Map();  // id -> {picture, place, onScreen, width}
    this.socket = null;
    this.sent = null;          // the watch message last sent on this socket, as text
    this.retryMs = FIRST_RETRY_MS;
    this.queued = false;
    this.visibility = new IntersectionObserver((entries) => {
      for (const entry of entries) {
        const camera = this.byPlace(entry.target);
        if (camera) camera.onScreen = entry.isIntersecting;
      }
      this.watchSoon();
    });
    this.sizes = new ResizeObserver((entries) => {
      for (const entry of entries) {
        const camera = this.byPlace(entry.target);
        if (camera) camera.width = entry.contentRect.width;
      }
      this.watchSoon();
    });
    document.addEventListener("visibilitychange", () => this.watchSoon());
  }

  byPlace(element) {
    for (const camera of this.cameras.values()) if (camera.place === element) return camera;
    return null;
  }

  /* picture.offer(header, jpeg) gets camera id's frames while place is on screen. */
  add(id, picture, place) {
    this.remove(id);
    this.cameras.set(id, { picture, place, onScreen: false, width: 0 });
    this.visibility.observe(place);
    this.sizes.observe(place);
  }

  remove(id) {
    const camera = this.cameras.get(id);
    if (!camera) return;
    this.visibility.unobserve(camera.place);
    this.sizes.unobserve(camera.place);
    this.cameras.delete(id);
    this.watchSoon();
  }

  /* Whether camera id's frames are wanted now. */
  watched(id) {
    const camera = this.cameras.get(id);
    return Boolean(camera && camera.onScreen && !document.hidden);
  }

  connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const socket = new WebSocket(`${scheme}://${location.host}/ws/live`);
    socket.binaryType = "arraybuffer";
    socket.onopen = () => {
      this.retryMs = FIRST_RETRY_MS;
      this.sent = null;
      this.sendWatch();
    };
    socket.onclose = () => {
      if (this.socket !== socket) return;
      this.socket = null;
      setTimeout(() => this.connect(), this.retryMs);
      this.retryMs = Math.min(this.retryMs * 2, LAST_RETRY_MS);
    };
    socket.onmessage = (event) => this.dispatch(event.data);
    this.socket = socket;
  }

  /* Messages come as fast as the network brings them; each is handed on at once, and the
     picture decodes only the newest (LivePicture): a busy page skips frames, it does not
     fall behind. */
  dispatch(data) {
    const message = parseLiveMessage(data);
    if (!message) return;
    const id = message.header.camera_id;
    if (this.watched(id)) this.cameras.get(id).picture.offer(message.header, message.jpeg);
  }

  /* One watch message for every change made in this task (observers fire in batches). */
  watchSoon() {
    if (this.queued) return;
    this.queued = true;
    queueMicrotask(() => {
      this.queued = false;
      this.sendWatch();
    });
  }

  sendWatch() {
    const socket = this.socket;
    if (!socket || socket.readyState !== WebSocket.OPEN) return;
    const ids = [];
    let width = 0;
    for (const [id, camera] of this.cameras) {
      if (!this.watched(id)) continue;
      ids.push(id);
      width = Math.max(width, camera.width);
    }
    const pixels = Math.ceil((width * (window.devicePixelRatio || 1)) / WIDTH_STEP) * WIDTH_STEP;
    const text = JSON.stringify({ type: "watch", cameras: ids.sort((a, b) => a - b), width: pixels });
    if (text === this.sent) return;
    this.sent = text;
    socket.send(text);
  }
}
