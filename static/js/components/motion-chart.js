/* A camera's motion over the last minute (% of the picture), with its alarms as red lines.
   Drawn with uPlot, loaded before the modules as a classic script (the global uPlot). */

const WINDOW_S = 60;
const HEIGHT = 120;
const MIN_WIDTH = 120;
const AXIS = { stroke: "#8b95a3", grid: { stroke: "#2c333d" }, ticks: { stroke: "#2c333d" } };

export class MotionChart {
  /* alarmTimes(): the times of the camera's last alarms (seconds). */
  constructor(element, alarmTimes) {
    this.element = element;
    this.alarmTimes = alarmTimes;
    this.points = [];  // {t, v}: the motion share (0..1) at each status, oldest first
    this.plot = null;  // made at the first drawing
    // Drawn only while on screen (not on the wall, not scrolled away), and again as it comes
    // back: a page of many cameras gets a status a second from each.
    this.onScreen = false;
    new IntersectionObserver(([entry]) => {
      this.onScreen = entry.isIntersecting;
      if (this.onScreen) this.draw(Date.now() / 1000);
    }).observe(element);
  }

  record(ts, value) {
    this.points.push({ t: ts, v: value });
    while (this.points.length && this.points[0].t < ts - WINDOW_S) this.points.shift();
    this.draw(ts);
  }

  draw(now) {
    if (!this.onScreen) return;
    const plot = this.ensurePlot();
    if (!plot) return;
    const shown = this.points.filter((p) => p.t >= now - WINDOW_S);
    plot.setData([shown.map((p) => p.t), shown.map((p) => p.v * 100)], false);
    plot.setScale("x", { min: now - WINDOW_S, max: now });
  }

  /* The plot, or null without uPlot (its script failed to load: the rest of the page works). */
  ensurePlot() {
    if (this.plot || !window.uPlot) return this.plot;
    const width = Math.max(MIN_WIDTH, this.element.clientWidth || 256);
    this.plot = new window.uPlot({
      width, height: HEIGHT,
      legend: { show: false },
      cursor: { show: false },
      scales: { x: { time: true }, y: { range: (u, min, max) => [0, Math.max(0.5, max * 1.1)] } },
      axes: [{ ...AXIS, size: 24 }, { ...AXIS, size: 36 }],
      series: [{}, { label: "motion %", stroke: "#6cf", width: 1.5, fill: "rgba(102,204,255,0.15)" }],
      hooks: { draw: [(u) => this.drawAlarms(u)] },
    }, [[], []], this.element);
    new ResizeObserver(() => {
      const fit = Math.max(MIN_WIDTH, this.element.clientWidth);
      if (Math.abs(fit - this.plot.width) > 2) this.plot.setSize({ width: fit, height: HEIGHT });
    }).observe(this.element);
    return this.plot;
  }

  drawAlarms(u) {
    const ctx = u.ctx;
    ctx.save();
    ctx.strokeStyle = "#e5484d";
    ctx.lineWidth = 2;
    for (const t of this.alarmTimes()) {
      const x = u.valToPos(t, "x", true);
      if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) continue;
      ctx.beginPath();
      ctx.moveTo(x, u.bbox.top);
      ctx.lineTo(x, u.bbox.top + u.bbox.height);
      ctx.stroke();
    }
    ctx.restore();
  }
}
