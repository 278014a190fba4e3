/* Vigil dashboard: plain JS, no build step. Talks to /api/* and listens on /ws. */
"use strict";

const $ = (selector, root = document) => root.querySelector(selector);
const $$ = (selector, root = document) => Array.from(root.querySelectorAll(selector));

/* Browsers keep about six HTTP/1.1 connections per host. Up to STREAM_LIMIT cameras
   get an MJPEG stream each; with more, every picture is polled as single frames.
   Histograms are always polled, so API calls keep a free connection. */
const STREAM_LIMIT = 4;
const POLL_MS = 250;
const HISTOGRAM_MS = 1000;
const MOTION_WINDOW_S = 60;

const state = {
  cameras: new Map(),      // id -> camera (from the API, updated by /ws status)
  cards: new Map(),        // id -> card element
  motion: new Map(),       // id -> [{t, v}]
  alarmsAt: new Map(),     // id -> [t]
  muted: localStorage.getItem("vigil.muted") === "1",
  streaming: null,         // whether pictures are MJPEG streams (vs polled frames)
  analyses: new Map(),     // id -> element
};

/* ---------- HTTP ---------- */

/* A 401 means the session has ended (or never began): log in, then come back here. */
function toLogin() {
  location.assign(`/login?next=${encodeURIComponent(location.pathname + location.search)}`);
}

async function api(method, url, body) {
  const options = { method, headers: {} };
  if (body !== undefined) {
    options.headers["Content-Type"] = "application/json";
    options.body = JSON.stringify(body);
  }
  const response = await fetch(url, options);
  if (response.status === 401) {
    toLogin();
    throw new Error("logged out");
  }
  if (!response.ok) {
    let detail = response.statusText;
    try {
      const data = await response.json();
      detail = typeof data.detail === "string" ? data.detail
        : (data.detail || []).map((d) => d.msg).join("; ") || detail;
    } catch (_) { /* not JSON */ }
    throw new Error(detail);
  }
  return response.status === 204 ? null : response.json();
}

function fmtTime(ts) {
  return new Date(ts * 1000).toLocaleTimeString();
}

function fmtDate(ts) {
  return new Date(ts * 1000).toLocaleString();
}

/* ---------- Sound and toasts ---------- */

let audio = null;
document.addEventListener("click", () => {
  if (!audio && window.AudioContext) audio = new AudioContext();
}, { once: false });

function beep() {
  if (state.muted || !audio) return;
  const now = audio.currentTime;
  for (const [offset, freq] of [[0, 880], [0.18, 660]]) {
    const osc = audio.createOscillator();
    const gain = audio.createGain();
    osc.type = "square";
    osc.frequency.value = freq;
    gain.gain.setValueAtTime(0.08, now + offset);
    gain.gain.exponentialRampToValueAtTime(0.0001, now + offset + 0.15);
    osc.connect(gain).connect(audio.destination);
    osc.start(now + offset);
    osc.stop(now + offset + 0.16);
  }
}

function renderMute() {
  const button = $("#mute");
  button.textContent = state.muted ? "🔕 Sound off" : "🔔 Sound on";
  button.setAttribute("aria-pressed", String(state.muted));
}

$("#mute").addEventListener("click", () => {
  state.muted = !state.muted;
  localStorage.setItem("vigil.muted", state.muted ? "1" : "0");
  renderMute();
});

function toast(html, kind = "alarm") {
  const el = document.createElement("div");
  el.className = `toast toast-${kind}`;
  el.innerHTML = html;
  el.addEventListener("click", () => el.remove());
  $("#toasts").prepend(el);
  setTimeout(() => el.remove(), 8000);
}

function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => ({
    "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}

/* ---------- Cameras ---------- */

function cameraName(id) {
  const camera = state.cameras.get(id);
  return camera ? camera.name : `camera ${id}`;
}

async function loadCameras() {
  try {
    const cameras = await api("GET", "/api/cameras");
    const seen = new Set();
    for (const camera of cameras) {
      seen.add(camera.id);
      state.cameras.set(camera.id, { ...(state.cameras.get(camera.id) || {}), ...camera });
    }
    for (const id of Array.from(state.cameras.keys())) {
      if (!seen.has(id)) {
        state.cameras.delete(id);
        const card = state.cards.get(id);
        if (card) {
          stopPictures(card);
          card.remove();
        }
        state.cards.delete(id);
      }
    }
    renderCameras();
    renderCameraFilter();
  } catch (error) {
    toast(`Cannot load cameras: ${escapeHtml(error.message)}`, "error");
  }
}

function renderCameras() {
  const streaming = state.cameras.size <= STREAM_LIMIT;
  const modeChanged = streaming !== state.streaming;
  state.streaming = streaming;
  for (const camera of state.cameras.values()) {
    let card = state.cards.get(camera.id);
    if (!card) {
      card = makeCard(camera.id);
      state.cards.set(camera.id, card);
      $("#grid").append(card);
    } else if (modeChanged && card._started) {
      stopPictures(card);
      startPictures(card, camera.id);
    }
    updateCard(card, camera);
  }
}

function makeCard(id) {
  const card = $("#camera-card").content.firstElementChild.cloneNode(true);
  card.dataset.id = id;
  const slider = $(".sensitivity", card);
  const auto = $(".auto", card);
  const output = $(".sens-value", card);
  let timer = null;
  slider.addEventListener("input", () => {
    output.textContent = slider.value;
    auto.checked = false;
    clearTimeout(timer);
    timer = setTimeout(() => patchCamera(id, { sensitivity: Number(slider.value) }), 150);
  });
  auto.addEventListener("change", () => {
    patchCamera(id, { sensitivity: auto.checked ? null : Number(slider.value) });
  });
  $(".mask", card).addEventListener("change", (e) => patchCamera(id, { show_mask: e.target.checked }));
  $(".min-area", card).addEventListener("change", (e) => {
    const value = Number(e.target.value);
    if (Number.isFinite(value) && value >= 0) patchCamera(id, { min_area: value });
  });
  $(".method", card).addEventListener("change", (e) => patchCamera(id, { method: e.target.value }));
  $(".toggle", card).addEventListener("click", async () => {
    const camera = state.cameras.get(id);
    try {
      const updated = await api("POST", `/api/cameras/${id}/${camera && camera.active ? "stop" : "activate"}`);
      state.cameras.set(id, { ...camera, ...updated });
      updateCard(card, state.cameras.get(id));
    } catch (error) {
      toast(escapeHtml(error.message), "error");
    }
  });
  setUpZones(card, id);
  $(".delete", card).addEventListener("click", async () => {
    if (!confirm(`Remove camera “${cameraName(id)}”? Its snapshots stay.`)) return;
    try {
      await api("DELETE", `/api/cameras/${id}`);
      loadCameras();
    } catch (error) {
      toast(escapeHtml(error.message), "error");
    }
  });
  return card;
}

/* ---------- Ignore zones ---------- */
// Polygons of [x, y] fractions of the frame (the API's `mask`), drawn in an SVG laid
// exactly over the picture as `object-fit: contain` shows it.

const SVG = "http://www.w3.org/2000/svg";

function setUpZones(card, id) {
  const picture = $(".picture", card);
  const img = $(".live", card);
  const layer = document.createElementNS(SVG, "svg");
  layer.classList.add("zone-layer");
  layer.setAttribute("viewBox", "0 0 1 1");
  layer.setAttribute("preserveAspectRatio", "none");
  picture.append(layer);
  const editor = { zones: [], draft: [] };
  card._zones = editor;

  const place = () => {
    if (!img.naturalWidth) return;
    const box = picture.getBoundingClientRect();
    const scale = Math.min(box.width / img.naturalWidth, box.height / img.naturalHeight);
    const width = img.naturalWidth * scale;
    const height = img.naturalHeight * scale;
    layer.style.left = `${(box.width - width) / 2}px`;
    layer.style.top = `${(box.height - height) / 2}px`;
    layer.style.width = `${width}px`;
    layer.style.height = `${height}px`;
  };
  const draw = () => {
    place();
    layer.replaceChildren();
    for (const zone of editor.zones) {
      const polygon = document.createElementNS(SVG, "polygon");
      polygon.setAttribute("points", zone.map(([x, y]) => `${x},${y}`).join(" "));
      layer.append(polygon);
    }
    if (editor.draft.length) {
      const line = document.createElementNS(SVG, "polyline");
      line.classList.add("draft");
      line.setAttribute("points", editor.draft.map(([x, y]) => `${x},${y}`).join(" "));
      layer.append(line);
      for (const [x, y] of editor.draft) {
        const dot = document.createElementNS(SVG, "circle");
        dot.setAttribute("cx", x);
        dot.setAttribute("cy", y);
        dot.setAttribute("r", 0.008);
        layer.append(dot);
      }
    }
  };
  let shown = null;  // The mask last drawn: status messages repeat it every second.
  editor.show = (mask) => {
    if (card.classList.contains("editing-zones")) return;  // Not while someone draws.
    const text = JSON.stringify(mask || []);
    if (text === shown) return;
    shown = text;
    editor.zones = (mask || []).map((zone) => zone.map(([x, y]) => [x, y]));
    draw();
  };
  const finishDraft = () => {
    if (editor.draft.length >= 3) editor.zones.push(editor.draft);
    editor.draft = [];
  };
  const stopEditing = () => {
    card.classList.remove("editing-zones");
    $(".zone-tools", card).hidden = true;
    editor.draft = [];
    shown = null;  // The drawing may differ from the saved mask: draw that again.
    editor.show(state.cameras.get(id)?.mask);
  };
  img.addEventListener("load", place);
  new ResizeObserver(draw).observe(picture);  // Gone with the card, unlike a window listener.
  layer.addEventListener("click", (event) => {
    const box = layer.getBoundingClientRect();
    const round = (value) => Math.round(Math.min(1, Math.max(0, value)) * 1000) / 1000;
    editor.draft.push([round((event.clientX - box.left) / box.width), round((event.clientY - box.top) / box.height)]);
    draw();
  });
  $(".zones", card).addEventListener("click", () => {
    card.classList.add("editing-zones");
    $(".zone-tools", card).hidden = false;
    draw();
  });
  $(".zone-finish", card).addEventListener("click", () => { finishDraft(); draw(); });
  $(".zone-clear", card).addEventListener("click", () => { editor.zones = []; editor.draft = []; draw(); });
  $(".zone-cancel", card).addEventListener("click", stopEditing);
  $(".zone-save", card).addEventListener("click", async () => {
    finishDraft();
    const zones = editor.zones;
    card.classList.remove("editing-zones");
    await patchCamera(id, { mask: zones.length ? zones : null });
    stopEditing();
  });
}

async function patchCamera(id, changes) {
  try {
    const updated = await api("PATCH", `/api/cameras/${id}`, changes);
    state.cameras.set(id, { ...state.cameras.get(id), ...updated });
    updateCard(state.cards.get(id), state.cameras.get(id));
  } catch (error) {
    toast(`Cannot change ${escapeHtml(cameraName(id))}: ${escapeHtml(error.message)}`, "error");
  }
}

function updateCard(card, camera) {
  if (!card || !camera) return;
  $(".cam-name", card).textContent = camera.name;
  $(".cam-name", card).title = camera.source;
  const badge = $(".state", card);
  badge.textContent = camera.state || "?";
  badge.className = `badge state badge-${camera.state}`;
  $(".fps", card).textContent = camera.state === "live" ? `${(camera.fps || 0).toFixed(1)} fps` : "";
  $(".reason", card).textContent = camera.reason || "";
  if (card._zones && "mask" in camera) card._zones.show(camera.mask);
  const toggle = $(".toggle", card);
  toggle.textContent = camera.active ? "Stop" : "Activate";
  toggle.classList.toggle("active", Boolean(camera.active));
  card.classList.toggle("watching", Boolean(camera.active));
  const slider = $(".sensitivity", card);
  const auto = $(".auto", card);
  if (document.activeElement !== slider) {
    const automatic = camera.sensitivity === null || camera.sensitivity === undefined;
    auto.checked = automatic;
    if (!automatic) slider.value = camera.sensitivity;
    const inForce = camera.threshold === null || camera.threshold === undefined ? "" : ` (${Math.round(camera.threshold)})`;
    $(".sens-value", card).textContent = automatic ? `auto${inForce}` : Math.round(camera.sensitivity);
  }
  if (document.activeElement !== $(".min-area", card)) $(".min-area", card).value = camera.min_area;
  $(".method", card).value = camera.method;
  $(".mask", card).checked = Boolean(camera.show_mask);
  // Pictures start once the camera has been live (a stream from a dead source would
  // hold a connection with nothing to show); they carry on across reconnects.
  if (!card._started && camera.state === "live") startPictures(card, camera.id);
  card.classList.toggle("no-picture", !card._started);
}

function startPictures(card, id) {
  const img = $(".live", card);
  const hist = $(".histogram", card);
  card._timers = [];
  card._started = true;
  if (state.streaming) {
    img.src = `/api/cameras/${id}/stream.mjpg`;
    img.onerror = () => retryLater(card, () => { img.src = `/api/cameras/${id}/stream.mjpg?r=${Date.now()}`; });
  } else {
    poll(card, img, `/api/cameras/${id}/frame.jpg`, POLL_MS);
  }
  poll(card, hist, `/api/cameras/${id}/histogram.jpg`, HISTOGRAM_MS);
}

function retryLater(card, action) {
  card._timers.push(setTimeout(action, 2000));
}

function poll(card, img, url, every) {
  const next = () => {
    if (!card.isConnected && card._stopped) return;
    card._timers.push(setTimeout(() => { img.src = `${url}?t=${Date.now()}`; }, every));
  };
  img.onload = next;
  img.onerror = () => card._timers.push(setTimeout(next, 1000));
  img.src = `${url}?t=${Date.now()}`;
}

function stopPictures(card) {
  card._stopped = true;
  for (const timer of card._timers || []) clearTimeout(timer);
  for (const img of $$("img", card)) {
    img.onload = null;
    img.onerror = null;
    img.removeAttribute("src");
  }
  card._stopped = false;
}

function recordMotion(id, ts, value) {
  const series = state.motion.get(id) || [];
  series.push({ t: ts, v: value });
  while (series.length && series[0].t < ts - MOTION_WINDOW_S) series.shift();
  state.motion.set(id, series);
  drawMotion(id, ts);
}

function motionChart(card) {
  if (card._chart || !window.uPlot) return card._chart || null;
  const el = $(".motion", card);
  const width = Math.max(200, el.clientWidth || 256);
  card._chart = new uPlot({
    width, height: 120,
    legend: { show: false },
    cursor: { show: false },
    scales: { x: { time: true }, y: { range: (u, min, max) => [0, Math.max(0.5, max * 1.1)] } },
    axes: [
      { stroke: "#8b95a3", grid: { stroke: "#2c333d" }, ticks: { stroke: "#2c333d" }, size: 24 },
      { stroke: "#8b95a3", grid: { stroke: "#2c333d" }, ticks: { stroke: "#2c333d" }, size: 36 },
    ],
    series: [{}, { label: "motion %", stroke: "#6cf", width: 1.5, fill: "rgba(102,204,255,0.15)" }],
    hooks: {
      draw: [(u) => {
        const alarms = state.alarmsAt.get(Number(card.dataset.id)) || [];
        const ctx = u.ctx;
        ctx.save();
        ctx.strokeStyle = "#e5484d";
        ctx.lineWidth = 2;
        for (const t of alarms) {
          const x = u.valToPos(t, "x", true);
          if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) continue;
          ctx.beginPath();
          ctx.moveTo(x, u.bbox.top);
          ctx.lineTo(x, u.bbox.top + u.bbox.height);
          ctx.stroke();
        }
        ctx.restore();
      }],
    },
  }, [[], []], el);
  return card._chart;
}

function drawMotion(id, now) {
  const card = state.cards.get(id);
  if (!card) return;
  const chart = motionChart(card);
  if (!chart) return;
  const series = (state.motion.get(id) || []).filter((p) => p.t >= now - MOTION_WINDOW_S);
  chart.setData([series.map((p) => p.t), series.map((p) => p.v * 100)], false);
  chart.setScale("x", { min: now - MOTION_WINDOW_S, max: now });
}

$("#add-camera").addEventListener("submit", async (event) => {
  event.preventDefault();
  const form = event.target;
  $("#add-camera-error").textContent = "";
  try {
    await api("POST", "/api/cameras", { name: form.name.value.trim(), source: form.source.value.trim() });
    form.reset();
    loadCameras();
  } catch (error) {
    $("#add-camera-error").textContent = error.message;
  }
});

/* ---------- Alarms ---------- */

function onAlarm(message) {
  const name = escapeHtml(message.camera_name || cameraName(message.camera_id));
  const count = (message.boxes || []).length;
  const list = state.alarmsAt.get(message.camera_id) || [];
  list.push(message.ts);
  state.alarmsAt.set(message.camera_id, list.slice(-50));
  toast(`<b>Motion on ${name}</b> at ${fmtTime(message.ts)} — ${count} object${count === 1 ? "" : "s"}`
    + (message.snapshot ? `<br><img src="${message.snapshot}" alt="snapshot">` : ""));
  beep();
  const item = document.createElement("li");
  item.dataset.event = message.event_id;
  // No snapshot when the disk refused it (full, read-only): the event still counts.
  const picture = message.snapshot
    ? `<a href="${message.snapshot}" target="_blank"><img src="${message.snapshot}" alt=""></a>`
    : '<span class="muted">snapshot not saved</span>';
  item.innerHTML = `${picture}
    <div><b>${name}</b> — ${fmtDate(message.ts)}<br>
    ${count} object${count === 1 ? "" : "s"}: ${(message.objects || []).map((o) =>
      `#${o.track_id ?? "?"} ${o.box[2]}×${o.box[3]} px at (${o.box[0]}, ${o.box[1]}), ${Math.round(o.speed_px_s)} px/s`).join(", ")}
    <br><span class="ongoing">moving…</span>
    ${message.difference ? `<a href="${message.difference}" target="_blank">difference</a>` : ""}</div>`;
  $("#alarm-list").prepend(item);
  while ($("#alarm-list").children.length > 100) $("#alarm-list").lastElementChild.remove();
  const card = state.cards.get(message.camera_id);
  if (card) {
    card.classList.remove("flash");
    void card.offsetWidth;
    card.classList.add("flash");
  }
  scheduleGallery();
}

function onMotionEnd(message) {
  const item = $(`#alarm-list li[data-event="${message.event_id}"] .ongoing`);
  if (item) item.textContent = `ended after ${message.duration_s.toFixed(1)} s, peak area ${Math.round(message.max_area)} px`;
}

$("#clear-alarms").addEventListener("click", () => { $("#alarm-list").innerHTML = ""; });

/* ---------- WebSocket ---------- */

let wsDelay = 500;

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const socket = new WebSocket(`${scheme}://${location.host}/ws`);
  const badge = $("#ws-state");
  socket.onopen = () => {
    wsDelay = 500;
    badge.textContent = "live";
    badge.className = "badge badge-live";
    loadCameras();
  };
  socket.onclose = () => {
    badge.textContent = "reconnecting";
    badge.className = "badge badge-reconnecting";
    setTimeout(connect, wsDelay);
    wsDelay = Math.min(wsDelay * 2, 10000);
  };
  socket.onmessage = (event) => {
    let message;
    try { message = JSON.parse(event.data); } catch (_) { return; }
    switch (message.type) {
      case "alarm": onAlarm(message); break;
      case "motion_end": onMotionEnd(message); break;
      case "progress": onProgress(message); break;
      case "status":
        if (message.camera_id !== undefined) onCameraStatus(message);
        else if (message.analysis_id !== undefined) refreshAnalysis(message.analysis_id);
        break;
      default: break;
    }
  };
}

function onCameraStatus(message) {
  const camera = state.cameras.get(message.camera_id);
  if (!camera) {
    loadCameras();
    return;
  }
  if ("storage_error" in message) {
    toast(message.storage_error
      ? `<b>Snapshots of ${escapeHtml(camera.name)} not saved:</b> ${escapeHtml(message.storage_error)}`
      : `Snapshots of ${escapeHtml(camera.name)} are saved again`, message.storage_error ? "error" : "info");
  }
  const { type, camera_id: _, storage_error: __, ...fields } = message;
  Object.assign(camera, fields);
  updateCard(state.cards.get(message.camera_id), camera);
  recordMotion(message.camera_id, Date.now() / 1000, message.motion || 0);
}

/* ---------- Uploads ---------- */

function analysisPanel(id, filename) {
  let panel = state.analyses.get(id);
  if (panel) return panel;
  panel = document.createElement("article");
  panel.className = "analysis";
  panel.innerHTML = `<header><b class="file"></b> <span class="badge status">queued</span></header>
    <label>Upload <progress class="upload-bar" max="1" value="1"></progress></label>
    <label>Analysis <progress class="analysis-bar" max="1" value="0"></progress> <span class="pct"></span></label>
    <div class="live-view"></div><p class="error"></p><div class="result"></div>`;
  $(".file", panel).textContent = filename || id;
  $("#analyses").prepend(panel);
  state.analyses.set(id, panel);
  return panel;
}

$("#upload").addEventListener("submit", (event) => {
  event.preventDefault();
  const form = event.target;
  const file = form.file.files[0];
  if (!file) return;
  const data = new FormData();
  data.append("file", file);
  data.append("method", form.method.value);
  if (form.sensitivity.value) data.append("sensitivity", form.sensitivity.value);
  if (form.min_area.value) data.append("min_area", form.min_area.value);
  const pending = analysisPanel(`upload-${Date.now()}`, file.name);
  const bar = $(".upload-bar", pending);
  bar.value = 0;
  $(".status", pending).textContent = "uploading";
  const xhr = new XMLHttpRequest();
  xhr.open("POST", "/api/analyses");
  xhr.upload.onprogress = (e) => { if (e.lengthComputable) bar.value = e.loaded / e.total; };
  xhr.onload = () => {
    if (xhr.status === 401) {
      toLogin();
      return;
    }
    let body = {};
    try { body = JSON.parse(xhr.responseText); } catch (_) { /* not JSON */ }
    if (xhr.status !== 202) {
      $(".status", pending).textContent = "failed";
      $(".error", pending).textContent = typeof body.detail === "string" ? body.detail : `upload failed (${xhr.status})`;
      return;
    }
    bar.value = 1;
    for (const [key, el] of state.analyses) if (el === pending) state.analyses.delete(key);
    state.analyses.set(body.id, pending);
    pending.dataset.id = body.id;
    refreshAnalysis(body.id);
    form.reset();
  };
  xhr.onerror = () => {
    $(".status", pending).textContent = "failed";
    $(".error", pending).textContent = "the upload was interrupted";
  };
  xhr.send(data);
});

function onProgress(message) {
  const panel = state.analyses.get(message.analysis_id);
  if (!panel) {
    refreshAnalysis(message.analysis_id);
    return;
  }
  $(".analysis-bar", panel).value = message.progress;
  $(".pct", panel).textContent = `${Math.round(message.progress * 100)} %`;
  if ($(".status", panel).textContent === "queued") setStatus(panel, message.analysis_id, "running");
}

function setStatus(panel, id, status) {
  const badge = $(".status", panel);
  badge.textContent = status;
  badge.className = `badge status badge-${status}`;
  const view = $(".live-view", panel);
  if (status === "running" && !$("img", view)) {
    view.innerHTML = `<img alt="analysis in progress" src="/api/analyses/${id}/stream.mjpg">`;
  }
}

async function refreshAnalysis(id) {
  let analysis;
  try {
    analysis = await api("GET", `/api/analyses/${id}`);
  } catch (_) {
    return;
  }
  const panel = analysisPanel(id, analysis.filename);
  setStatus(panel, id, analysis.status);
  $(".analysis-bar", panel).value = analysis.progress;
  $(".pct", panel).textContent = `${Math.round(analysis.progress * 100)} %`;
  $(".error", panel).textContent = analysis.error || "";
  if (analysis.status === "done" && !panel.dataset.rendered) {
    panel.dataset.rendered = "1";
    renderResult(panel, analysis);
  }
  if (analysis.status === "failed") $(".live-view", panel).innerHTML = "";
}

function renderResult(panel, analysis) {
  const links = analysis.links;
  const report = analysis.report || {};
  const rows = (report.tracks || []).map((t) => `<tr><td>#${t.track_id}</td><td>${t.first_frame}–${t.last_frame}</td>
    <td>${t.duration_s}</td><td>${t.distance_px}</td><td>${t.mean_speed_px_s}</td><td>${t.max_speed_px_s}</td>
    <td>${t.distance_m ?? ""}</td><td>${t.mean_speed_km_h ?? ""}</td></tr>`).join("");
  $(".live-view", panel).innerHTML = `<img alt="last analysed frame" src="${links.stream}?end=1">`;
  $(".result", panel).innerHTML = `
    <p>${report.frames ?? "?"} frames at ${report.fps ?? "?"} fps, ${report.events ?? 0} events,
      ${(report.tracks || []).length} tracked objects, method ${escapeHtml(report.method ?? "")}.</p>
    <p class="links"><a href="${links.annotated}">annotated.avi</a> · <a href="${links.tracks}">tracks.csv</a> ·
      <a href="${links.report_html}" target="_blank">report</a> · <a href="${links.report}" target="_blank">report.json</a></p>
    <table class="tracks"><thead><tr><th>track</th><th>frames</th><th>duration s</th><th>distance px</th>
      <th>mean px/s</th><th>max px/s</th><th>distance m</th><th>km/h</th></tr></thead><tbody>${rows
      || '<tr><td colspan="8">no moving objects found</td></tr>'}</tbody></table>`;
}

async function loadAnalyses() {
  try {
    const analyses = await api("GET", "/api/analyses");
    for (const analysis of analyses.slice(0, 10).reverse()) refreshAnalysis(analysis.id);
  } catch (_) { /* shown on the next action */ }
}

/* ---------- Snapshot gallery ---------- */

function renderCameraFilter() {
  const select = $("#gallery-filter select[name=camera_id]");
  const current = select.value;
  select.innerHTML = '<option value="">all</option>' + Array.from(state.cameras.values())
    .map((c) => `<option value="${c.id}">${escapeHtml(c.name)}</option>`).join("");
  select.value = current;
}

function galleryQuery() {
  const form = $("#gallery-filter");
  const params = new URLSearchParams();
  if (form.camera_id.value) params.set("camera_id", form.camera_id.value);
  if (form.kind.value) params.set("kind", form.kind.value);
  if (form.since.value) params.set("since", String(new Date(form.since.value).getTime() / 1000));
  if (form.until.value) params.set("until", String(new Date(form.until.value).getTime() / 1000));
  return params;
}

async function loadGallery() {
  const params = galleryQuery();
  $("#zip-all").href = `/api/snapshots.zip?${params}`;
  params.set("limit", "200");
  let snapshots;
  try {
    snapshots = await api("GET", `/api/snapshots?${params}`);
  } catch (error) {
    toast(`Cannot load snapshots: ${escapeHtml(error.message)}`, "error");
    return;
  }
  const selected = new Set($$("#thumbs input:checked").map((i) => i.value));
  $("#thumbs").innerHTML = snapshots.map((s) => `<figure class="thumb">
      <label><input type="checkbox" value="${s.id}" ${selected.has(String(s.id)) ? "checked" : ""}>
      <img loading="lazy" src="${s.url}" alt="snapshot ${s.id}"></label>
      <figcaption>${escapeHtml(cameraName(s.camera_id))} · ${fmtDate(s.ts)} · ${s.kind}</figcaption>
    </figure>`).join("") || '<p class="muted">No snapshots yet: Activate a camera.</p>';
  updateZipSelected();
}

let galleryTimer = null;
function scheduleGallery() {
  clearTimeout(galleryTimer);
  galleryTimer = setTimeout(loadGallery, 1000);
}

function selectedIds() {
  return $$("#thumbs input:checked").map((i) => Number(i.value));
}

function updateZipSelected() {
  const ids = selectedIds();
  const link = $("#zip-selected");
  link.href = ids.length ? `/api/snapshots.zip?ids=${ids.join(",")}` : "#";
  link.classList.toggle("disabled", !ids.length);
}

$("#thumbs").addEventListener("change", updateZipSelected);
$("#select-all").addEventListener("change", (e) => {
  for (const box of $$("#thumbs input")) box.checked = e.target.checked;
  updateZipSelected();
});
$("#zip-selected").addEventListener("click", (e) => { if (!selectedIds().length) e.preventDefault(); });
$("#delete-selected").addEventListener("click", async () => {
  const ids = selectedIds();
  if (!ids.length || !confirm(`Delete ${ids.length} snapshot(s)?`)) return;
  try {
    await api("POST", "/api/snapshots/delete", { ids });
  } catch (error) {
    toast(escapeHtml(error.message), "error");
  }
  $("#select-all").checked = false;
  loadGallery();
});
$("#gallery-filter").addEventListener("submit", (e) => { e.preventDefault(); loadGallery(); });

/* ---------- Start ---------- */

renderMute();
loadCameras().then(loadGallery);
loadAnalyses();
connect();
setInterval(loadCameras, 15000);
setInterval(() => { for (const id of state.cameras.keys()) drawMotion(id, Date.now() / 1000); }, 1000);
