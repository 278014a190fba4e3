/* The Snapshots section: a run of the listing (newest first, by time then id), from the
   newest snapshot its filters match down to the oldest shown; "Show older" adds the next
   page. A snapshot is a cursor into the listing, its time and id (the API's until/until_id
   and since/since_id), so snapshots that share a time at a page's edge are neither
   skipped nor shown twice; and "Download all shown" asks for the run shown, ends
   included. Selected snapshots can be downloaded or deleted. */
import { api } from "../api/client.js";
import { $, $$, escapeHtml } from "../lib/dom.js";
import { formatDate, plural } from "../lib/format.js";

const PAGE = 200;   // Snapshots the gallery shows at first, and adds on "Show older".
const MAX = 9999;   // The most shown: one more than this is the most one listing gives.
const REFRESH_DELAY_MS = 1000;  // After an alarm: its snapshots are saved by then.
const GONE_NOTE = '<div class="gone-note">snapshot deleted</div>';

function endAt(params, end, snap, id = snap.id) {
  params.set(end, String(snap.ts));
  params.set(`${end}_id`, String(id));
}

export class Gallery {
  /* cameraName(id); noteCamera(id) for each camera shown; deleted(ids) after this page
     deleted snapshots (the alarm list and the toasts drop them). */
  constructor(section, { cameraName, noteCamera, deleted, toasts }) {
    this.section = section;
    this.cameraName = cameraName;
    this.noteCamera = noteCamera;
    this.deleted = deleted;
    this.toasts = toasts;
    this.form = $("#gallery-filter", section);
    this.thumbs = $("#thumbs", section);
    this.olderButton = $("#gallery-more", section);
    this.selectAll = $("#select-all", section);
    this.filters = null;     // the filters shown (URLSearchParams)
    this.snapshots = [];     // those shown, newest first
    this.more = false;       // whether older ones match too
    this.oldest = null;      // the oldest shown: where older ones start
    this.gone = new Set();   // the ids of those shown that have been deleted elsewhere
    // Listings run one after another (each builds on what the last showed); a refresh
    // waiting for its turn, if any, stands for any asked meanwhile.
    this.queue = Promise.resolve();
    this.waiting = null;
    this.refreshTimer = null;
    this.wireControls();
  }

  wireControls() {
    this.form.addEventListener("submit", (e) => { e.preventDefault(); this.load("fresh"); });
    this.olderButton.addEventListener("click", () => this.showOlder());
    this.thumbs.addEventListener("change", () => this.renderSelection());
    this.selectAll.addEventListener("change", (e) => {
      for (const box of $$("input", this.thumbs)) box.checked = e.target.checked;
      this.renderSelection();
    });
    $("#zip-selected", this.section).addEventListener("click", (e) => { if (!this.selectedIds().length) e.preventDefault(); });
    $("#zip-all", this.section).addEventListener("click", (e) => { if (e.currentTarget.classList.contains("disabled")) e.preventDefault(); });
    $("#delete-selected", this.section).addEventListener("click", () => this.deleteSelected());
  }

  query() {
    const form = this.form;
    const params = new URLSearchParams();
    if (form.camera_id.value) params.set("camera_id", form.camera_id.value);
    if (form.kind.value) params.set("kind", form.kind.value);
    if (form.since.value) params.set("since", String(new Date(form.since.value).getTime() / 1000));
    if (form.until.value) params.set("until", String(new Date(form.until.value).getTime() / 1000));
    return params;
  }

  /* Asks for a listing; its snapshots, or null where it failed (said in a toast). */
  async list(params) {
    try {
      return await api("GET", `/api/snapshots?${params}`);
    } catch (error) {
      this.toasts.show(`Cannot load snapshots: ${escapeHtml(error.message)}`, "error");
      return null;
    }
  }

  /* Runs a task after the listings asked for before it: an alarm's refresh and "Show
     older" each build on what the other showed, and neither answer is lost. */
  enqueue(task) {
    const run = this.queue.then(task);
    this.queue = run.catch(() => {});
    return run;
  }

  /* How the gallery is listed again:
     - "fresh": from the newest, with the filters of the form (new filters, the page opened);
     - "shown": the same filters, as far down as shown, with what came in since on top (the
       server back: snapshots may have been deleted or pruned meanwhile);
     - "newer": only what came in after the newest shown, put on top (an alarm: listing again
       all that is shown, up to MAX, would be a large request for each alarm).
     One refresh waiting for its turn stands for any asked meanwhile ("shown" for "newer"). */
  load(how = "newer") {
    if (how !== "fresh") {
      if (this.waiting) {
        if (how === "shown") this.waiting = how;
        return this.queue;
      }
      this.waiting = how;
    }
    return this.enqueue(() => {
      if (how === "fresh") return this.refresh(true);
      const waited = this.waiting;
      this.waiting = null;
      return waited === "newer" ? this.listNewer() : this.refresh(false);
    });
  }

  /* An alarm's snapshots, listed a moment later (several alarms: once). */
  scheduleRefresh() {
    clearTimeout(this.refreshTimer);
    this.refreshTimer = setTimeout(() => this.load("newer"), REFRESH_DELAY_MS);
  }

  async refresh(fresh) {
    if (fresh || !this.filters) this.filters = this.query();
    const params = new URLSearchParams(this.filters);
    const shown = fresh ? [] : this.snapshots;
    // Older ones are not shown: stay down to the oldest shown (deleted since, it still counts).
    const down = !fresh && this.more && this.oldest !== null;
    if (down) endAt(params, "since", this.oldest);
    const limit = Math.min(MAX, shown.length + PAGE);
    params.set("limit", String(limit + 1));  // One more tells whether there are more.
    const snapshots = await this.list(params);
    if (!snapshots) return;
    const cut = snapshots.length > limit;  // So many came in that the oldest shown fall off.
    this.snapshots = snapshots.slice(0, limit);
    this.gone.clear();  // Listed as the server has them: none deleted among them.
    if (cut || !down) this.oldest = this.snapshots.at(-1) || null;
    this.more = down || cut;
    this.render();
  }

  /* The snapshots taken after the newest shown (its time, then the ids after it: the
     listing's cursor), on top of those shown. */
  async listNewer() {
    const newest = this.snapshots[0];
    if (!newest) return this.refresh(false);
    const params = new URLSearchParams(this.filters);
    endAt(params, "since", newest, newest.id + 1);
    params.set("limit", String(PAGE + 1));  // One more tells whether some were left out.
    const newer = await this.list(params);
    if (!newer) return;
    // More than a page at once: those left out would be a hole below them. As far down as shown.
    if (newer.length > PAGE) return this.refresh(false);
    const shown = new Set(this.snapshots.map((s) => s.id));
    const added = newer.filter((s) => !shown.has(s.id));
    if (!added.length) return;
    const snapshots = added.concat(this.snapshots);
    this.snapshots = snapshots.slice(0, MAX);
    if (snapshots.length > MAX) {  // The oldest shown fall off.
      this.oldest = this.snapshots.at(-1);
      this.more = true;
    }
    this.render();
  }

  showOlder() {
    this.olderButton.disabled = true;
    return this.enqueue(() => this.showOlderPage()).finally(() => { this.olderButton.disabled = false; });
  }

  async showOlderPage() {
    const room = Math.min(PAGE, MAX - this.snapshots.length);
    if (this.oldest === null || room <= 0) return;
    const params = new URLSearchParams(this.filters);
    endAt(params, "until", this.oldest, this.oldest.id - 1);
    params.set("limit", String(room + 1));
    const older = await this.list(params);
    if (!older) return;
    const page = older.slice(0, room);
    this.snapshots = this.snapshots.concat(page);
    if (page.length) this.oldest = page.at(-1);
    this.more = older.length > room;
    this.render();
  }

  thumbHtml(snap, selected) {
    const gone = this.gone.has(snap.id);
    const picture = gone ? GONE_NOTE : `<label><input type="checkbox" value="${snap.id}" ${selected ? "checked" : ""}>
      <img loading="lazy" src="${snap.url}" alt="snapshot ${snap.id}"></label>`;
    return `<figure class="thumb${gone ? " gone" : ""}" data-id="${snap.id}">${picture}
      <figcaption>${escapeHtml(this.cameraName(snap.camera_id))} · ${formatDate(snap.ts)} · ${snap.kind}</figcaption>
    </figure>`;
  }

  render() {
    const { snapshots, more } = this;
    for (const snap of snapshots) this.noteCamera(snap.camera_id);
    const selected = new Set($$("input:checked", this.thumbs).map((i) => i.value));
    this.thumbs.innerHTML = snapshots.map((s) => this.thumbHtml(s, selected.has(String(s.id)))).join("")
      || `<p class="muted">${more ? "None left here: older ones are below." : "No snapshots yet: Activate a camera."}</p>`;
    this.renderTotals();
  }

  /* The count, "Show older" and "Download all shown": of the snapshots shown, those not
     deleted elsewhere (the zip asks for the run from the newest to the oldest of them). */
  renderTotals() {
    const { snapshots, more, filters, gone } = this;
    const kept = snapshots.filter((s) => !gone.has(s.id));
    const full = snapshots.length >= MAX;  // As many as a page holds: no more below.
    this.olderButton.hidden = !more || full;
    $("#gallery-count", this.section).textContent = !snapshots.length ? ""
      : `${plural(kept.length, "snapshot")} shown, newest first`
        + `${!more ? "" : full ? ": for older ones, filter by time" : ", older ones below"}`;
    const zip = $("#zip-all", this.section);
    const params = new URLSearchParams(filters);
    if (kept.length) {
      endAt(params, "until", kept[0]);
      endAt(params, "since", kept[kept.length - 1]);
      params.set("limit", String(kept.length));
    }
    zip.href = kept.length ? `/api/snapshots.zip?${params}` : "#";
    zip.classList.toggle("disabled", !kept.length);
    zip.textContent = `Download all ${kept.length} shown (.zip)`;
    this.renderSelection();
  }

  selectedIds() {
    return $$("input:checked", this.thumbs).map((i) => Number(i.value));
  }

  renderSelection() {
    const ids = this.selectedIds();
    const link = $("#zip-selected", this.section);
    link.href = ids.length ? `/api/snapshots.zip?ids=${ids.join(",")}` : "#";
    link.classList.toggle("disabled", !ids.length);
    // "select all" says what is ticked: a snapshot that arrives after it was ticked comes
    // unticked (the user has not seen it to delete it), and so unticks it.
    const shown = $$("input", this.thumbs).length;
    this.selectAll.checked = shown > 0 && ids.length === shown;
  }

  async deleteSelected() {
    const ids = this.selectedIds();
    if (!ids.length || !confirm(`Delete ${ids.length} snapshot(s)?`)) return;
    try {
      this.deleted((await api("POST", "/api/snapshots/delete", { ids })).deleted);
    } catch (error) {
      this.toasts.show(escapeHtml(error.message), "error");
      return;
    }
    // Off the gallery, all of them: those the server did not delete now were gone already.
    // After any listing under way, which may still have them.
    const deleted = new Set(ids);
    this.selectAll.checked = false;
    this.enqueue(() => {
      this.snapshots = this.snapshots.filter((s) => !deleted.has(s.id));
      this.render();
    });
  }

  /* Snapshots deleted on the server, by any page or by pruning. Their tiles are greyed
     after any listing under way (which may have been answered before they went): in
     place, so no tile moves under the pointer, but out of the count, the selection and
     the zips. */
  markGone(ids) {
    this.enqueue(() => {
      const deleted = new Set(ids);
      const shown = this.snapshots.filter((s) => deleted.has(s.id) && !this.gone.has(s.id));
      if (!shown.length) return;
      for (const { id } of shown) {
        this.gone.add(id);
        const tile = $(`.thumb[data-id="${id}"]`, this.thumbs);  // The gallery may have been drawn again.
        if (!tile) continue;
        tile.classList.add("gone");
        const label = $("label", tile);  // With its checkbox: no longer to select.
        if (label) label.outerHTML = GONE_NOTE;
      }
      this.renderTotals();
    });
  }
}
