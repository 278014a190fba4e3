/* The gallery's camera filter: the cameras there are, and those deleted whose events or
   snapshots are still listed. */
import { escapeHtml } from "../lib/dom.js";

export class CameraFilter {
  constructor(select, cameras) {
    this.select = select;
    this.cameras = cameras;
    this.known = new Set();  // cameras that have events or snapshots, deleted ones too
  }

  /* A camera id seen in an event or a snapshot. */
  note(id) {
    if (id === null || id === undefined || this.known.has(id)) return;
    this.known.add(id);
    if (this.cameras.loaded && !this.cameras.has(id)) this.render();
  }

  render() {
    const { select, cameras } = this;
    const current = select.value;
    const deleted = Array.from(this.known).filter((id) => !cameras.has(id)).sort((a, b) => a - b);
    select.innerHTML = '<option value="">all</option>' + Array.from(cameras.values())
      .map((c) => `<option value="${c.id}">${escapeHtml(c.name)}</option>`).join("")
      + (cameras.loaded ? deleted.map((id) => `<option value="${id}">${escapeHtml(cameras.name(id))}</option>`).join("") : "");
    select.value = current;
    if (select.value !== current) select.value = "";
  }
}
