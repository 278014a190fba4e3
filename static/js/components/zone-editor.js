/* A camera's ignore zones: polygons of [x, y] fractions of the frame (the API's `mask`),
   drawn in an SVG laid exactly over the picture as the live picture letterboxes it. The
   user clicks corners on the picture to outline an area, then saves all areas at once. */
import { $ } from "../lib/dom.js";

const SVG = "http://www.w3.org/2000/svg";

function svgElement(name, attributes) {
  const element = document.createElementNS(SVG, name);
  for (const [key, value] of Object.entries(attributes)) element.setAttribute(key, value);
  return element;
}

const pointsText = (points) => points.map(([x, y]) => `${x},${y}`).join(" ");

export class ZoneEditor {
  /* savedMask(): the camera's mask in force; save(mask) stores a new one (null: none);
     frameSize(): the picture's [width, height], null before its first frame. */
  constructor(card, { savedMask, save, frameSize }) {
    this.card = card;
    this.picture = $(".picture", card);
    this.frameSize = frameSize;
    this.tools = $(".zone-tools", card);
    this.savedMask = savedMask;
    this.layer = svgElement("svg", { class: "zone-layer", viewBox: "0 0 1 1", preserveAspectRatio: "none" });
    this.picture.append(this.layer);
    this.zones = [];
    this.draft = [];         // the corners of the area being outlined
    this.editing = false;    // while someone draws, the saved mask is not drawn over it
    this.shownMask = null;   // the mask last drawn, as text: status messages repeat it every second
    new ResizeObserver(() => this.draw()).observe(this.picture);  // Gone with the card, unlike a window listener.
    this.layer.addEventListener("click", (event) => this.addCorner(event));
    $(".zones", card).addEventListener("click", () => {
      this.setEditing(true);
      this.tools.hidden = false;
      this.draw();
    });
    $(".zone-finish", card).addEventListener("click", () => { this.finishDraft(); this.draw(); });
    $(".zone-clear", card).addEventListener("click", () => { this.zones = []; this.draft = []; this.draw(); });
    $(".zone-cancel", card).addEventListener("click", () => this.stopEditing());
    $(".zone-save", card).addEventListener("click", async () => {
      this.finishDraft();
      const zones = this.zones;
      this.setEditing(false);
      await save(zones.length ? zones : null);
      this.stopEditing();
    });
  }

  /* Draws a camera's mask (undefined or null: no zones), unless someone is drawing. */
  show(mask) {
    if (this.editing) return;
    const text = JSON.stringify(mask || []);
    if (text === this.shownMask) return;
    this.shownMask = text;
    this.zones = (mask || []).map((zone) => zone.map(([x, y]) => [x, y]));
    this.draw();
  }

  setEditing(editing) {
    this.editing = editing;
    this.card.classList.toggle("editing-zones", editing);
  }

  stopEditing() {
    this.setEditing(false);
    this.tools.hidden = true;
    this.draft = [];
    this.shownMask = null;  // The drawing may differ from the saved mask: draw that again.
    this.show(this.savedMask());
  }

  finishDraft() {
    if (this.draft.length >= 3) this.zones.push(this.draft);
    this.draft = [];
  }

  addCorner(event) {
    const box = this.layer.getBoundingClientRect();
    const round = (value) => Math.round(Math.min(1, Math.max(0, value)) * 1000) / 1000;
    this.draft.push([round((event.clientX - box.left) / box.width), round((event.clientY - box.top) / box.height)]);
    this.draw();
  }

  /* The layer over the picture's frame, not the letterbox around it (called again when
     the frame's size changes). */
  place() {
    const size = this.frameSize();
    if (!size) return;
    const box = this.picture.getBoundingClientRect();
    const scale = Math.min(box.width / size[0], box.height / size[1]);
    const width = size[0] * scale;
    const height = size[1] * scale;
    Object.assign(this.layer.style, {
      left: `${(box.width - width) / 2}px`,
      top: `${(box.height - height) / 2}px`,
      width: `${width}px`,
      height: `${height}px`,
    });
  }

  draw() {
    this.place();
    this.layer.replaceChildren(...this.zones.map((zone) => svgElement("polygon", { points: pointsText(zone) })));
    if (!this.draft.length) return;
    this.layer.append(svgElement("polyline", { class: "draft", points: pointsText(this.draft) }));
    for (const [x, y] of this.draft) this.layer.append(svgElement("circle", { cx: x, cy: y, r: 0.008 }));
  }
}
