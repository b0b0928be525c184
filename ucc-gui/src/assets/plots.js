// Plots over time with axes and values (uPlot, vendored: vendor/uPlot.iife.min.js).
import { boxSize } from "./map2d.js";
const SERIES = [["altitude", "m", 1, "#d62839"], ["speed", "m/s", 2, "#2f6690"], ["battery", "level", 3, "#1b7a6e"]];

export class Plots {
  constructor(box) {
    this.box = box; this.plots = []; this.key = null;
    if (!window.uPlot) { const p = document.createElement("p"); p.textContent = "plots unavailable"; box.appendChild(p); return; }
    for (const [name, unit, , color] of SERIES) {
      const opts = {
        width: this.width(), height: 95, legend: { show: true }, cursor: { drag: { x: false, y: false } },
        scales: { x: { time: false } },
        // The y axis is labelled with the unit only (the legend names the series): a
        // 95 px plot has no room for "altitude (m)" written upwards.
        axes: [{ label: "simulated time (s)", labelSize: 14, size: 28 }, { label: unit, labelSize: 14, size: 44 }],
        series: [{ label: "t" }, { label: name, stroke: color, width: 1.5 }],
      };
      this.plots.push(new window.uPlot(opts, [[], []], box));
    }
  }

  width() { return Math.max(200, boxSize(this.box)[0] - 16); }

  /** Shows the history of `c` (`[t, altitude, speed, battery]` rows); cheap when unchanged. */
  draw(c) {
    if (!this.plots.length) return;
    const h = c ? c.history : [];
    const key = c ? `${c.info.id}:${h.length}:${h.length ? h[h.length - 1][0] : 0}:${this.width()}` : "none";
    if (key === this.key) return;
    this.key = key;
    const t = h.map((r) => r[0]);
    this.plots.forEach((p, i) => {
      if (p.width !== this.width()) p.setSize({ width: this.width(), height: 95 });
      p.setData([t, h.map((r) => r[SERIES[i][2]])]);
    });
  }
}
