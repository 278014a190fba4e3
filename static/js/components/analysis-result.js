/* A finished analysis in words and a table: frames, events, the tracked objects; and its
   annotated video to play, its events as chapters to jump to. */
import { escapeHtml } from "../lib/dom.js";
import { decimals, plural } from "../lib/format.js";

function clock(seconds) {
  const minutes = Math.floor(seconds / 60);
  return `${minutes}:${(seconds - minutes * 60).toFixed(1).padStart(4, "0")}`;
}

/* The annotated video (annotated.mp4) and a button per event, which seeks to its start
   (analyses.js follows them). */
export function playerHtml(analysis) {
  const chapters = (analysis.events || []).map((e) => `<li><button type="button" class="chapter"
    data-at="${Number(e.start_time_s)}" title="frames ${e.start_frame}–${e.end_frame}">Event ${e.id} at
    ${clock(e.start_time_s)} (${decimals(e.end_time_s - e.start_time_s, 1)} s)</button></li>`).join("");
  return `<video class="annotated" controls muted playsinline preload="auto"
    src="${analysis.links.annotated_mp4}"></video>
    ${chapters ? `<ol class="chapters" aria-label="events">${chapters}</ol>` : ""}`;
}

export function resultHtml(analysis) {
  const links = analysis.links;
  const report = analysis.report || {};
  const tracks = report.tracks || [];
  // Metres and km/h only with a calibrated camera: otherwise the columns stay out.
  const calibrated = tracks.some((t) => (t.distance_m ?? null) !== null || (t.mean_speed_km_h ?? null) !== null);
  const rows = tracks.map((t) => `<tr><td>#${t.track_id}</td><td>${t.first_frame}–${t.last_frame}</td>
    <td>${decimals(t.duration_s, 2)}</td><td>${decimals(t.distance_px, 1)}</td><td>${decimals(t.mean_speed_px_s, 1)}</td>
    <td>${decimals(t.max_speed_px_s, 1)}</td>${calibrated
      ? `<td>${decimals(t.distance_m, 2)}</td><td>${decimals(t.mean_speed_km_h, 1)}</td>` : ""}</tr>`).join("");
  const columns = calibrated ? 8 : 6;
  const events = report.events ?? 0;
  // What the input did not give whole (frames that did not decode, an early end), or
  // what the settings cannot find: said on the page as the report says it.
  const warnings = (report.warnings || []).map((w) => `<li>${escapeHtml(w)}</li>`).join("");
  return `
    <p>${report.frames ?? "?"} frames at ${report.fps ?? "?"} fps, ${plural(events, "event")},
      ${plural(tracks.length, "tracked object")}, method ${escapeHtml(report.method ?? "")}.</p>
    ${warnings ? `<ul class="warnings">${warnings}</ul>` : ""}
    <p class="links"><a href="${links.annotated_mp4}" download>annotated.mp4</a> · <a href="${links.annotated}">annotated.avi</a> · <a href="${links.tracks}">tracks.csv</a> ·
      <a href="${links.report_html}" target="_blank">report</a> · <a href="${links.report}" target="_blank">report.json</a></p>
    <div class="table-wrap"><table class="tracks"><thead><tr><th>track</th><th>frames</th><th>duration s</th>
      <th>distance px</th><th>mean px/s</th><th>max px/s</th>${calibrated ? "<th>distance m</th><th>km/h</th>" : ""}
      </tr></thead><tbody>${rows
      || `<tr><td colspan="${columns}">no moving objects found</td></tr>`}</tbody></table></div>`;
}
