/* The Events section: per camera, a day's timeline (how much of the picture moved, and
   every event on it), a day to pick and an hour to zoom to; an event clicked plays its
   clip beside its snapshot and details, with the previous and next event a click away.
   An alarm's toast opens its event here (open). */
import { api } from "../api/client.js";
import { Timeline } from "../components/timeline.js";
import { $, escapeHtml } from "../lib/dom.js";
import { formatDate, formatTime, plural } from "../lib/format.js";

const POINTS = 720;         // Steps a timeline asks for: about one per two pixels.
const MAX_EVENTS = 5000;    // The most events one listing gives.
const RELOAD_DELAY_MS = 1500;  // After an alarm or a motion_end: its clip is written by then.

function dayValue(date) {
  const pad = (n) => String(n).padStart(2, "0");
  return `${date.getFullYear()}-${pad(date.getMonth() + 1)}-${pad(date.getDate())}`;
}

function seconds(value) {
  return value === null || value === undefined ? "" : `${Number(value).toFixed(1)} s`;
}

export class EventsView {
  /* cameras: the page's Cameras; toasts, for errors. An event deleted here takes its
     snapshots with it: /ws tells every page (snapshots_deleted). */
  constructor(section, { cameras, toasts }) {
    this.section = section;
    this.cameras = cameras;
    this.toasts = toasts;
    this.form = $("#events-filter", section);
    this.strips = $("#timelines", section);
    this.player = $(".event-player", section);
    this.video = $("video", this.player);
    this.timelines = new Map();  // camera id -> Timeline
    this.events = [];            // the window's events, oldest first
    this.selected = null;        // the event shown in the player
    this.reloadTimer = null;
    this.loading = Promise.resolve();
    this.form.day.value = dayValue(new Date());
    this.wire();
  }

  wire() {
    const { form } = this;
    form.addEventListener("submit", (e) => { e.preventDefault(); this.load(); });
    form.addEventListener("change", () => this.load());
    $(".day-prev", form).addEventListener("click", () => this.moveDay(-1));
    $(".day-next", form).addEventListener("click", () => this.moveDay(1));
    $(".event-prev", this.player).addEventListener("click", () => this.step(-1));
    $(".event-next", this.player).addEventListener("click", () => this.step(1));
    $(".event-delete", this.player).addEventListener("click", () => this.deleteSelected());
    this.video.addEventListener("error", () => {
      if (this.selected?.clip) this.note("The clip does not play here (deleted, or the server is away).");
    });
  }

  moveDay(by) {
    const day = this.dayStart();
    day.setDate(day.getDate() + by);
    this.form.day.value = dayValue(day);
    this.load();
  }

  dayStart() {
    const [year, month, date] = (this.form.day.value || dayValue(new Date())).split("-").map(Number);
    return new Date(year, month - 1, date);
  }

  /* The span shown: the day, or its chosen hour. */
  span() {
    const start = this.dayStart();
    const hour = this.form.hour.value;
    if (hour === "") {
      const end = new Date(start);
      end.setDate(end.getDate() + 1);
      return { since: start.getTime() / 1000, until: end.getTime() / 1000 };
    }
    start.setHours(Number(hour));
    return { since: start.getTime() / 1000, until: start.getTime() / 1000 + 3600 };
  }

  zoomTo(ts) {
    if (this.form.hour.value !== "") return;
    this.form.hour.value = String(new Date(ts * 1000).getHours());
    this.load();
  }

  /* Loads are made one after another: a later one shows what is newest. */
  load() {
    this.loading = this.loading.then(() => this.loadNow()).catch((error) => {
      this.toasts.show(`Events: ${escapeHtml(error.message)}`, "error");
    });
    return this.loading;
  }

  async loadNow() {
    const { since, until } = this.span();
    const step = Math.max(1, Math.ceil((until - since) / POINTS));
    const cameraId = this.form.camera_id.value;
    const filter = cameraId ? `&camera_id=${cameraId}` : "";
    const listed = await api("GET", `/api/events?since=${since}&until=${until}&limit=${MAX_EVENTS}${filter}`);
    this.events = listed.filter((e) => e.started_at < until).sort((a, b) => a.started_at - b.started_at || a.id - b.id);
    const ids = cameraId ? [Number(cameraId)]
      : [...new Set([...Array.from(this.cameras.values(), (c) => c.id), ...this.events.map((e) => e.camera_id)])];
    const activity = await Promise.all(ids.map((id) => api("GET",
      `/api/cameras/${id}/activity?since=${since}&until=${until}&step=${step}`).catch(() => ({ steps: [] }))));
    const shown = new Set(ids);
    for (const [id, timeline] of this.timelines) {
      if (!shown.has(id)) {
        timeline.element.remove();
        this.timelines.delete(id);
      }
    }
    ids.forEach((id, i) => {
      const timeline = this.timeline(id);
      this.strips.append(timeline.element);  // In the order listed.
      timeline.draw({ since, until, steps: activity[i].steps, selectedId: this.selected?.id,
        events: this.events.filter((e) => e.camera_id === id) });
    });
    $(".events-count", this.section).textContent = `${plural(this.events.length, "event")}`
      + (this.events.length >= MAX_EVENTS ? " (the first shown)" : "");
    const fresh = this.selected && this.events.find((e) => e.id === this.selected.id);
    if (fresh) this.refreshSelected(fresh);
    this.showButtons();
  }

  timeline(id) {
    let timeline = this.timelines.get(id);
    if (!timeline) {
      timeline = new Timeline({ cameraId: id, name: this.cameras.name(id),
        pick: (event) => this.select(event), zoom: (ts) => this.zoomTo(ts) });
      this.timelines.set(id, timeline);
    }
    return timeline;
  }

  /* An event from elsewhere on the page (a toast, the alarm list): its day and hour shown,
     the event playing. */
  async open(eventId) {
    let event;
    try {
      event = await api("GET", `/api/events/${eventId}`);
    } catch (error) {
      this.toasts.show(`Event ${eventId}: ${escapeHtml(error.message)}`, "error");
      return;
    }
    const at = new Date(event.started_at * 1000);
    this.form.day.value = dayValue(at);
    this.form.hour.value = String(at.getHours());
    if (this.form.camera_id.value && Number(this.form.camera_id.value) !== event.camera_id) {
      this.form.camera_id.value = "";
    }
    this.selected = event;
    await this.load();
    this.select(this.events.find((e) => e.id === event.id) || event);
    this.section.scrollIntoView({ block: "start" });
  }

  select(event) {
    if (!event) return;
    this.selected = event;
    this.player.hidden = false;
    for (const timeline of this.timelines.values()) timeline.select(event.id);
    this.showDetails(event);
    this.note(event.clip ? (event.clip_s === null ? "Still recording: it plays as far as it has got." : "")
      : `No clip${event.clip_error ? `: ${event.clip_error}` : "."}`);
    if (event.clip) {
      this.video.src = event.clip;
      this.video.play().catch(() => { /* the user presses play */ });
    } else {
      this.video.removeAttribute("src");
      this.video.load();
    }
    this.showButtons();
  }

  /* The selected event as the newest listing has it: a clip that finished recording is
     played again from where it was. */
  refreshSelected(fresh) {
    const finished = this.selected.clip_s === null && fresh.clip_s !== null;
    this.selected = fresh;
    this.showDetails(fresh);
    if (finished && fresh.clip) {
      const { currentTime, paused } = this.video;
      this.note("");
      this.video.src = `${fresh.clip}?v=${fresh.clip_bytes}`;
      this.video.addEventListener("loadedmetadata", () => {
        this.video.currentTime = currentTime;
        if (!paused) this.video.play().catch(() => {});
      }, { once: true });
    }
  }

  showDetails(event) {
    const shot = $(".event-snapshot", this.player);
    shot.hidden = !event.snapshot;
    if (event.snapshot) shot.src = event.snapshot;
    const duration = event.ended_at === null ? "going on" : seconds(event.ended_at - event.started_at);
    const facts = [
      ["Camera", this.cameras.name(event.camera_id)],
      ["Started", formatDate(event.started_at)],
      ["Lasted", duration],
      ["Objects", String((event.track_ids || []).length || (event.boxes || []).length)],
      ["Largest area", `${Math.round(event.max_area)} px`],
      ["Clip", event.clip ? `${event.clip_s === null ? "recording" : seconds(event.clip_s)}`
        + (event.clip_started_at ? `, from ${formatTime(event.clip_started_at)}` : "") : "none"],
    ];
    if (event.clip_error) facts.push(["Note", event.clip_error]);
    $(".event-facts", this.player).innerHTML = facts
      .map(([name, value]) => `<dt>${name}</dt><dd>${escapeHtml(value)}</dd>`).join("");
    const download = $(".clip-download", this.player);
    download.hidden = !event.clip;
    if (event.clip) download.href = event.clip;
    this.player.dataset.event = event.id;
  }

  note(text) {
    $(".player-note", this.player).textContent = text;
  }

  position() {
    return this.selected ? this.events.findIndex((e) => e.id === this.selected.id) : -1;
  }

  showButtons() {
    const at = this.position();
    $(".event-prev", this.player).disabled = at <= 0;
    $(".event-next", this.player).disabled = at < 0 || at >= this.events.length - 1;
  }

  step(by) {
    const next = this.events[this.position() + by];
    if (next) this.select(next);
  }

  async deleteSelected() {
    const event = this.selected;
    if (!event) return;
    try {
      await api("DELETE", `/api/events/${event.id}`);
    } catch (error) {
      this.toasts.show(`Not deleted: ${escapeHtml(error.message)}`, "error");
      return;
    }
    const next = this.events[this.position() + 1] || this.events[this.position() - 1];
    this.video.removeAttribute("src");
    this.video.load();
    this.selected = null;
    this.player.hidden = true;
    await this.load();
    if (next) this.select(this.events.find((e) => e.id === next.id));
  }

  /* An alarm or a motion_end: a window that reaches the present is loaded again, soon
     (once for a burst of them; a camera that alarms every second still gets a load). */
  heard() {
    if (this.reloadTimer || this.span().until < Date.now() / 1000 - 60) return;
    this.reloadTimer = setTimeout(() => {
      this.reloadTimer = null;
      this.load();
    }, RELOAD_DELAY_MS);
  }
}
