/* A camera's live picture: the newest frame from /ws/live drawn on a canvas and, in the
   same paint, what the detector found in that frame: the motion mask tinted red, each
   track's trail, a red box per object with its track id and speed. The picture is
   letterboxed in the canvas as `object-fit: contain` would show it.

   Frames may come faster than they decode (a busy page, a burst): one decode at a time,
   and the next is the newest frame that came meanwhile; the others are dropped. */

const RED = "rgb(255, 0, 0)";
const TRAIL = "rgb(255, 200, 0)";  // The annotated MJPEG's colours.
const MASK_ALPHA = 0.5;            // The mask's tint: half red, half picture.

/* Picture bytes (a JPEG, a PNG) decoded, off the main thread: a VideoFrame or an
   ImageBitmap, each drawn by drawImage and let go by close(). WebCodecs' ImageDecoder
   takes the bytes as they are; a Blob for createImageBitmap (where ImageDecoder is
   missing: pages not served over https or from this machine) goes through the browser
   process, and cost a page showing 16 cameras a fifth of its main thread. */
async function decodePicture(bytes, type) {
  if (typeof ImageDecoder === "function") {
    const decoder = new ImageDecoder({ data: bytes, type });
    try {
      return (await decoder.decode()).image;
    } finally {
      decoder.close();
    }
  }
  return createImageBitmap(new Blob([bytes], { type }));
}

/* A base64 PNG mask (0 / 255, detection size) as a canvas, red where it is set and clear
   elsewhere, to draw over the picture at MASK_ALPHA. */
async function maskTint(base64) {
  const bytes = Uint8Array.from(atob(base64), (c) => c.charCodeAt(0));
  const picture = await decodePicture(bytes, "image/png");
  const tint = document.createElement("canvas");
  tint.width = picture.displayWidth ?? picture.width;
  tint.height = picture.displayHeight ?? picture.height;
  const context = tint.getContext("2d", { willReadFrequently: true });
  context.drawImage(picture, 0, 0);
  picture.close();
  const pixels = context.getImageData(0, 0, tint.width, tint.height);
  const data = pixels.data;
  for (let i = 0; i < data.length; i += 4) {
    const set = data[i] > 127;
    data[i] = 255;
    data[i + 1] = 0;
    data[i + 2] = 0;
    data[i + 3] = set ? 255 : 0;
  }
  context.putImageData(pixels, 0, 0);
  return tint;
}

/* A ResizeObserver entry's size in device pixels: [width, height]. */
function devicePixels(entry) {
  const box = entry.devicePixelContentBoxSize?.[0];
  if (box) return [box.inlineSize, box.blockSize];
  const ratio = window.devicePixelRatio || 1;
  return [Math.round(entry.contentRect.width * ratio), Math.round(entry.contentRect.height * ratio)];
}

function label(detection) {
  if (detection.track_id === null || detection.track_id === undefined) return "";
  return `#${detection.track_id} ${Math.round(detection.speed_px_s)} px/s`;
}

export class LivePicture {
  /* canvas: where frames are drawn; onFrame(header): after each frame is drawn. */
  constructor(canvas, onFrame = () => {}) {
    this.canvas = canvas;
    this.context = canvas.getContext("2d");
    this.onFrame = onFrame;
    this.waiting = null;  // the newest frame not decoded yet: {header, jpeg (its bytes)}
    this.decoding = false;
    this.frame = null;    // the frame shown: {header, bitmap, tint}
    this.drawn = 0;
    // The canvas's size in device pixels, as the ResizeObserver last told it: read from
    // the layout at each frame, it made the page lay out again at each frame.
    this.pixels = [0, 0];
    const sizes = new ResizeObserver(([entry]) => {
      this.pixels = devicePixels(entry);
      this.draw();
    });
    try {
      sizes.observe(canvas, { box: "device-pixel-content-box" });  // a new screen's ratio too
    } catch (_) {
      sizes.observe(canvas);  // a browser without that box
    }
  }

  /* The frame's size ([width, height] of the camera's picture) once one has come. */
  get size() {
    return this.frame ? this.frame.header.size : null;
  }

  offer(header, jpeg) {
    this.waiting = { header, jpeg };
    if (!this.decoding) this.decodeNext();
  }

  async decodeNext() {
    const next = this.waiting;
    this.waiting = null;
    if (!next) return;
    this.decoding = true;
    try {
      const [bitmap, tint] = await Promise.all([
        decodePicture(next.jpeg, "image/jpeg"),
        next.header.mask ? maskTint(next.header.mask) : null,
      ]);
      this.show({ header: next.header, bitmap, tint });
    } catch (_) {
      // A picture that does not decode is skipped; the next one is drawn.
    } finally {
      this.decoding = false;
      if (this.waiting) this.decodeNext();
    }
  }

  show(frame) {
    const before = this.frame;
    this.frame = frame;
    if (before) before.bitmap.close();
    this.draw();
    this.drawn += 1;
    this.canvas.dataset.frame = frame.header.frame;
    this.canvas.dataset.drawn = this.drawn;
    this.canvas.liveHeader = frame.header;  // What is drawn, for a test or the console to read.
    this.onFrame(frame.header);
  }

  /* No picture until the next frame. */
  clear() {
    if (this.frame) this.frame.bitmap.close();
    this.frame = null;
    this.waiting = null;
    this.context.clearRect(0, 0, this.canvas.width, this.canvas.height);
  }

  /* The picture's place in the canvas, in canvas pixels: {x, y, scale}. */
  placement() {
    const [width, height] = this.frame.header.size;
    const scale = Math.min(this.canvas.width / width, this.canvas.height / height);
    return { x: (this.canvas.width - width * scale) / 2, y: (this.canvas.height - height * scale) / 2, scale };
  }

  draw() {
    const { canvas, context, frame } = this;
    const ratio = window.devicePixelRatio || 1;
    const [width, height] = this.pixels;
    if (canvas.width !== width || canvas.height !== height) {
      canvas.width = width;
      canvas.height = height;
    }
    context.clearRect(0, 0, width, height);
    if (!frame || !width || !height) return;
    const [frameWidth, frameHeight] = frame.header.size;
    const { x, y, scale } = this.placement();
    context.drawImage(frame.bitmap, x, y, frameWidth * scale, frameHeight * scale);
    if (frame.tint) {
      context.save();
      context.globalAlpha = MASK_ALPHA;
      context.imageSmoothingEnabled = false;  // Whole pixels of the mask, as the server draws it.
      context.drawImage(frame.tint, x, y, frameWidth * scale, frameHeight * scale);
      context.restore();
    }
    this.drawDetections(frame.header.detections || [], x, y, scale, ratio);
  }

  drawDetections(detections, x, y, scale, ratio) {
    const context = this.context;
    const at = ([px, py]) => [x + px * scale, y + py * scale];
    context.save();
    context.lineWidth = ratio;
    context.strokeStyle = TRAIL;
    for (const detection of detections) {
      const trail = detection.trail || [];
      if (trail.length < 2) continue;
      context.beginPath();
      context.moveTo(...at(trail[0]));
      for (const point of trail.slice(1)) context.lineTo(...at(point));
      context.stroke();
    }
    const fontPx = Math.round(11 * ratio);
    context.font = `${fontPx}px system-ui, sans-serif`;
    context.textBaseline = "top";
    context.lineWidth = 2 * ratio;
    for (const detection of detections) {
      const [bx, by, bw, bh] = detection.box;
      const [left, top] = at([bx, by]);
      context.strokeStyle = RED;
      context.strokeRect(left, top, bw * scale, bh * scale);
      const text = label(detection);
      if (!text) continue;
      const textWidth = context.measureText(text).width;
      const labelTop = Math.max(0, top - fontPx - 4 * ratio);
      context.fillStyle = RED;
      context.fillRect(left, labelTop, textWidth + 6 * ratio, fontPx + 4 * ratio);
      context.fillStyle = "white";
      context.fillText(text, left + 3 * ratio, labelTop + 2 * ratio);
    }
    context.restore();
  }
}
