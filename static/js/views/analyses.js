/* The "Analyse a video" section: the upload form, and a panel per analysis (the recent
   ones on page load, each new upload) with its progress, live picture and result. */
import { api, toLogin } from "../api/client.js";
import { $, $$ } from "../lib/dom.js";
import { playerHtml, resultHtml } from "../components/analysis-result.js";

const DISMISSED_KEY = "vigil.dismissedAnalyses";
const SHOWN_ON_LOAD = 10;
const FINISHED = ["done", "failed", "cancelled"];

function dismissedAnalyses() {
  try {
    return JSON.parse(localStorage.getItem(DISMISSED_KEY) || "[]");
  } catch (_) {
    return [];
  }
}

/* Dismissed panels stay away across reloads (the last 200 remembered). */
function rememberDismissed(id) {
  const dismissed = dismissedAnalyses().filter((d) => d !== id);
  dismissed.push(id);
  localStorage.setItem(DISMISSED_KEY, JSON.stringify(dismissed.slice(-200)));
}

class AnalysisPanel {
  constructor(id, filename, dismiss) {
    this.element = document.createElement("article");
    this.element.className = "analysis";
    this.setId(id);
    this.rendered = false;  // A done analysis's result is drawn once.
    this.status = "queued";
    this.element.innerHTML = `<header><b class="file"></b> <span class="badge status">queued</span>
    <button type="button" class="cancel" hidden>Cancel upload</button>
    <button type="button" class="dismiss" title="remove this panel (the analysis stays on the server)"
      aria-label="dismiss" hidden>✕</button></header>
    <label>Upload <progress class="upload-bar" max="1" value="1"></progress></label>
    <label>Analysis <progress class="analysis-bar" max="1" value="0"></progress> <span class="pct"></span></label>
    <div class="live-view"></div><p class="error"></p><div class="result"></div>`;
    this.part(".file").textContent = filename || id;
    this.part(".dismiss").addEventListener("click", () => dismiss(this));
    this.element.addEventListener("click", (event) => {
      const chapter = event.target.closest(".chapter");
      if (chapter) this.playFrom(Number(chapter.dataset.at));
    });
  }

  /* The analysis's id, or "upload-<time>" until the server has given one. */
  setId(id) {
    this.id = id;
    this.element.dataset.id = id;
  }

  part(selector) {
    return $(selector, this.element);
  }

  /* "uploading", then the analysis's status (queued, running, done, failed, cancelled). */
  setStatus(status) {
    this.status = status;
    const badge = this.part(".status");
    badge.textContent = status;
    badge.className = `badge status badge-${status}`;
    this.part(".dismiss").hidden = !FINISHED.includes(status);
  }

  setProgress(progress) {
    this.part(".analysis-bar").value = progress;
    this.part(".pct").textContent = `${Math.round(progress * 100)} %`;
  }

  setError(text) {
    this.part(".error").textContent = text;
  }

  /* A place for the live stream, opened by showStreams; false if the view has a picture. */
  addLiveStream() {
    const view = this.part(".live-view");
    if ($("img", view)) return false;
    view.innerHTML = `<img class="streaming" alt="analysis in progress" data-stream="/api/analyses/${this.id}/stream.mjpg">`;
    return true;
  }

  showResult(analysis) {
    this.part(".live-view").innerHTML = playerHtml(analysis);
    this.part(".result").innerHTML = resultHtml(analysis);
  }

  /* An event's chapter button: the video from that event's start. */
  playFrom(seconds) {
    const video = this.part("video.annotated");
    if (!video) return;
    video.currentTime = seconds;
    video.play().catch(() => { /* the user presses play */ });
  }
}

export class Analyses {
  constructor(container, form) {
    this.container = container;
    this.panels = new Map();   // id -> AnalysisPanel
    this.uploads = new Set();  // the uploads under way (XMLHttpRequest)
    form.addEventListener("submit", (event) => {
      event.preventDefault();
      this.upload(event.target);
    });
    // Leaving the page (reload, close, another address) ends an upload under way: the
    // browser asks first.
    window.addEventListener("beforeunload", (event) => {
      if (!this.uploads.size) return;
      event.preventDefault();
      event.returnValue = "";  // What older browsers ask for.
    });
  }

  panel(id, filename) {
    let panel = this.panels.get(id);
    if (panel) return panel;
    panel = new AnalysisPanel(id, filename, (dismissed) => this.dismiss(dismissed));
    this.container.prepend(panel.element);
    this.panels.set(id, panel);
    return panel;
  }

  dismiss(panel) {
    if (!panel.id.startsWith("upload-")) rememberDismissed(panel.id);
    this.panels.delete(panel.id);
    panel.element.remove();
  }

  setStatus(panel, status) {
    panel.setStatus(status);
    if (status === "running" && panel.addLiveStream()) this.showStreams();
  }

  /* The streams of the analyses watched live: open while the page is shown, closed while
     it is hidden (each comes back when shown). */
  showStreams() {
    for (const img of $$(".live-view img.streaming", this.container)) {
      if (document.hidden) img.removeAttribute("src");
      else if (!img.getAttribute("src")) img.src = img.dataset.stream;
    }
  }

  upload(form) {
    const file = form.file.files[0];
    if (!file) return;
    const data = new FormData();
    data.append("file", file);
    data.append("method", form.method.value);
    if (form.sensitivity.value) data.append("sensitivity", form.sensitivity.value);
    if (form.min_area.value) data.append("min_area", form.min_area.value);
    const pending = this.panel(`upload-${Date.now()}`, file.name);
    const bar = pending.part(".upload-bar");
    bar.value = 0;
    pending.setStatus("uploading");
    const xhr = new XMLHttpRequest();
    xhr.open("POST", "/api/analyses");
    xhr.upload.onprogress = (e) => { if (e.lengthComputable) bar.value = e.loaded / e.total; };
    const cancel = pending.part(".cancel");
    cancel.hidden = false;
    // Sent whole, the video is the server's to analyse: nothing is left to cancel.
    xhr.upload.onload = () => { cancel.hidden = true; };
    cancel.addEventListener("click", () => xhr.abort());
    this.uploads.add(xhr);
    xhr.onloadend = () => {
      this.uploads.delete(xhr);
      cancel.hidden = true;
    };
    xhr.onabort = () => {
      this.setStatus(pending, "cancelled");
      pending.setError("Upload cancelled: the video was not sent.");
    };
    xhr.onload = () => {
      if (xhr.status === 401) {
        toLogin();
        return;
      }
      let body = {};
      try { body = JSON.parse(xhr.responseText); } catch (_) { /* not JSON */ }
      if (xhr.status !== 202) {
        this.setStatus(pending, "failed");
        pending.setError(typeof body.detail === "string" ? body.detail : `upload failed (${xhr.status})`);
        return;
      }
      bar.value = 1;
      this.panels.delete(pending.id);
      this.panels.set(body.id, pending);
      pending.setId(body.id);
      this.refresh(body.id);
      form.reset();
    };
    xhr.onerror = () => {
      this.setStatus(pending, "failed");
      pending.setError("the upload was interrupted");
    };
    xhr.send(data);
  }

  onProgress(message) {
    const panel = this.panels.get(message.analysis_id);
    if (!panel) {
      this.refresh(message.analysis_id);
      return;
    }
    panel.setProgress(message.progress);
    if (panel.status === "queued") this.setStatus(panel, "running");
  }

  async refresh(id) {
    let analysis;
    try {
      analysis = await api("GET", `/api/analyses/${id}`);
    } catch (_) {
      return;
    }
    const panel = this.panel(id, analysis.filename);
    this.setStatus(panel, analysis.status);
    panel.setProgress(analysis.progress);
    panel.setError(analysis.error || "");
    if (analysis.status === "done" && !panel.rendered) {
      panel.rendered = true;
      panel.showResult(analysis);
    }
    if (analysis.status === "failed") panel.part(".live-view").innerHTML = "";
  }

  async load() {
    try {
      const dismissed = new Set(dismissedAnalyses());
      const analyses = (await api("GET", "/api/analyses")).filter((a) => !dismissed.has(a.id)).slice(0, SHOWN_ON_LOAD);
      // Panels made now, oldest first (each goes on top), so the newest stays on top
      // whatever order their details arrive in.
      for (const analysis of analyses.slice().reverse()) this.panel(analysis.id, analysis.filename);
      for (const analysis of analyses) this.refresh(analysis.id);
    } catch (_) { /* shown on the next action */ }
  }
}
