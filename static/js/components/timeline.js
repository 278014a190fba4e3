/* One camera's day (or hour) as a strip: the share of its picture that moved, as an area
   over time (GET /api/cameras/{id}/activity), and each event as a mark to click. Where the
   camera was not activated there is no history: a grey band says so. Drawn in SVG across
   the width it is given; the hour labels are HTML, so they keep their shape. */
import { formatTime } from "../lib/format.js";

const SVG = "http://www.w3.org/2000/svg";
const WIDTH = 1000;   // viewBox units across, whatever the pixels
const HEIGHT = 60;
const SMALLEST_TOP = 0.01;  // The scale tops at the span's largest share, at least 1 %.
const PICK_PX = 6;    // A click this near an event's mark picks it.

function svg(name, attributes = {}) {
  const element = document.createElementNS(SVG, name);
  for (const [key, value] of Object.entries(attributes)) element.setAttribute(key, value);
  return element;
}

function twoDigits(value) {
  return String(value).padStart(2, "0");
}

/* Runs of steps with a motion (the camera watching), as [first, last] indices. */
function watchedRuns(steps) {
  const runs = [];
  let start = null;
  steps.forEach((step, i) => {
    const watched = step.motion !== null && step.motion !== undefined;
    if (watched && start === null) start = i;
    if (!watched && start !== null) {
      runs.push([start, i - 1]);
      start = null;
    }
  });
  if (start !== null) runs.push([start, steps.length - 1]);
  return runs;
}

export class Timeline {
  /* name: the camera's; pick(event) on a click on an event's mark; zoom(ts) on a click
     elsewhere (the day view zooms to that hour). */
  constructor({ cameraId, name, pick, zoom }) {
    this.cameraId = cameraId;
    this.pick = pick;
    this.zoom = zoom;
    this.events = new Map();  // id -> event shown
    this.element = document.createElement("div");
    this.element.className = "timeline";
    this.element.dataset.camera = cameraId;
    this.element.innerHTML = `<div class="timeline-head"><b class="timeline-name"></b>
      <span class="timeline-peak muted"></span></div><div class="timeline-strip"></div>
      <div class="timeline-ticks"></div>`;
    this.element.querySelector(".timeline-name").textContent = name;
    this.svg = svg("svg", { viewBox: `0 0 ${WIDTH} ${HEIGHT}`, preserveAspectRatio: "none", role: "img" });
    this.element.querySelector(".timeline-strip").append(this.svg);
    this.svg.addEventListener("click", (event) => this.clicked(event));
    this.svg.addEventListener("keydown", (event) => {
      if ((event.key === "Enter" || event.key === " ") && event.target.dataset.event) {
        event.preventDefault();
        this.pick(this.events.get(Number(event.target.dataset.event)));
      }
    });
  }

  x(ts) {
    return ((ts - this.since) / (this.until - this.since)) * WIDTH;
  }

  /* since, until: the span (UNIX seconds); steps: the activity's; events: the camera's. */
  draw({ since, until, steps, events, selectedId }) {
    this.since = since;
    this.until = until;
    this.svg.replaceChildren();
    const step = steps.length ? (until - since) / steps.length : 1;
    const runs = watchedRuns(steps);
    let unwatchedFrom = since;
    for (const [first, last] of [...runs, [steps.length, steps.length]]) {
      const runStart = since + first * step;
      if (runStart > unwatchedFrom) {
        this.svg.append(svg("rect", { class: "unwatched", x: this.x(unwatchedFrom), y: 0,
          width: this.x(runStart) - this.x(unwatchedFrom), height: HEIGHT }));
      }
      unwatchedFrom = since + (last + 1) * step;
    }
    const peak = Math.max(0, ...steps.map((s) => s.motion || 0));
    const top = Math.max(peak, SMALLEST_TOP);
    for (const [first, last] of runs) {
      const points = [`${this.x(since + first * step)},${HEIGHT}`];
      for (let i = first; i <= last; i += 1) {
        const y = HEIGHT - (steps[i].motion / top) * (HEIGHT - 4);
        points.push(`${this.x(since + i * step)},${y}`, `${this.x(since + (i + 1) * step)},${y}`);
      }
      points.push(`${this.x(since + (last + 1) * step)},${HEIGHT}`);
      this.svg.append(svg("polygon", { class: "motion-area", points: points.join(" ") }));
    }
    this.element.querySelector(".timeline-peak").textContent = runs.length
      ? `largest share moving: ${(peak * 100).toFixed(peak < 0.1 ? 2 : 1)} %` : "not watched";
    this.events = new Map(events.map((e) => [e.id, e]));
    for (const event of events) {
      const end = event.ended_at ?? Math.min(until, Date.now() / 1000);
      const left = Math.max(0, this.x(event.started_at));
      const mark = svg("rect", { class: "event-mark", x: left, y: 0, height: HEIGHT, tabindex: 0,
        width: Math.max(this.x(end) - left, 3), "data-event": event.id });
      const title = svg("title");
      title.textContent = `${formatTime(event.started_at)}, ${(end - event.started_at).toFixed(1)} s`
        + (event.clip ? "" : " (no clip)");
      mark.append(title);
      this.svg.append(mark);
    }
    this.drawTicks();
    this.select(selectedId);
  }

  drawTicks() {
    const span = this.until - this.since;
    const every = span > 4 * 3600 ? 3 * 3600 : span > 3600 ? 3600 : 600;
    const box = this.element.querySelector(".timeline-ticks");
    box.replaceChildren();
    for (let ts = Math.ceil(this.since / every) * every; ts < this.until; ts += every) {
      const at = new Date(ts * 1000);
      const tick = document.createElement("span");
      tick.textContent = `${twoDigits(at.getHours())}:${twoDigits(at.getMinutes())}`;
      // Through the style property, not a style attribute: the page's policy allows it.
      tick.style.left = `${(this.x(ts) / WIDTH) * 100}%`;
      if (ts === this.since) tick.classList.add("first");  // Not half off the strip.
      box.append(tick);
    }
  }

  select(eventId) {
    for (const mark of this.svg.querySelectorAll(".event-mark")) {
      mark.classList.toggle("selected", Number(mark.dataset.event) === eventId);
    }
  }

  /* A click picks the event nearest to it within a few pixels (marks of events seconds
     apart overlap on a day); elsewhere it asks to zoom to that time. */
  clicked(event) {
    const box = this.svg.getBoundingClientRect();
    const span = this.until - this.since;
    const at = this.since + ((event.clientX - box.left) / box.width) * span;
    const reach = (PICK_PX / box.width) * span;
    let nearest = null;
    let distance = Infinity;
    for (const shown of this.events.values()) {
      const end = shown.ended_at ?? shown.started_at;
      const away = at < shown.started_at ? shown.started_at - at : Math.max(0, at - end);
      if (away < distance) [nearest, distance] = [shown, away];
    }
    if (nearest && distance <= reach) this.pick(nearest);
    else this.zoom(at);
  }
}
