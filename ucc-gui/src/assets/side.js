// Side views: north (x) against altitude and east (y) against altitude, with axes, the
// obstacles as their extent and height, this iteration's trail and the past ones.
import { range, ticks, WALL_COLOR } from "./logic.js";
import { sizeCanvas } from "./map2d.js";

/** One side view on `canvas`; `axis` 0 draws x (north), 1 draws y (east). */
export class SideView {
  constructor(canvas, axis) { this.canvas = canvas; this.axis = axis; this.range = null; this.labels = []; }

  draw(c, geometry, overlay) {
    const [W, H] = sizeCanvas(this.canvas), ctx = this.canvas.getContext("2d"), k = this.axis;
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, W, H);
    ctx.font = "10px sans-serif"; this.labels = [];
    if (!c) { this.caption(W); this.range = null; return; }
    const segs = overlay ? c.past.concat([c.trail]) : [c.trail];
    const hs = [], vs = [0];
    for (const s of segs) for (const p of s) { hs.push(p[k]); vs.push(-p[2]); }
    for (const m of c.info.missions) if (m.kind === "GotoXyz") { hs.push(k === 0 ? m.x : m.y); vs.push(-m.z); }
    let hr = range(hs) || [-1, 1], vr = range(vs);
    if (hr[1] - hr[0] < 2) hr = [hr[0] - 1, hr[1] + 1];
    vr = [Math.min(0, vr[0]), Math.max(vr[1] + 0.5, 1)];
    this.range = hr;
    const L = 30, B = 14, X = (h) => L + (h - hr[0]) / (hr[1] - hr[0]) * (W - L - 6), Z = (z) => H - B - (z - vr[0]) / (vr[1] - vr[0]) * (H - B - 6);
    // Obstacles in this slice of the world: their extent along the axis and their heights.
    if (geometry) {
      ctx.fillStyle = WALL_COLOR; ctx.globalAlpha = 0.5;
      for (const f of geometry) {
        const r = range(f.outline.map((p) => p[k]));
        if (!r || r[1] < hr[0] || r[0] > hr[1] || -f.z_min > vr[1] + 5) continue;
        const x0 = X(Math.max(r[0], hr[0])), x1 = X(Math.min(r[1], hr[1]));
        const z0 = Z(Math.max(-f.z_max, vr[0])), z1 = Z(Math.min(-f.z_min, vr[1]));
        if (x1 - x0 > (W - L) * 0.95 && z0 - z1 > (H - B) * 0.9) continue; // the room around it all
        ctx.fillRect(x0, z1, Math.max(1, x1 - x0), Math.max(1, z0 - z1));
      }
      ctx.globalAlpha = 1;
    }
    // Axes with values.
    ctx.strokeStyle = "#999"; ctx.lineWidth = 1; ctx.beginPath();
    ctx.moveTo(L, 4); ctx.lineTo(L, H - B); ctx.lineTo(W - 4, H - B); ctx.stroke();
    ctx.fillStyle = "#1a1a1a";
    for (const t of ticks(hr[0], hr[1], 6)) { const x = X(t); ctx.fillRect(x, H - B, 1, 3); this.text(String(+t.toFixed(2)), x - 6, H - 2); }
    for (const t of ticks(vr[0], vr[1], 3)) { const y = Z(t); ctx.fillRect(L - 3, y, 3, 1); this.text(String(+t.toFixed(2)), 2, y + 3); }
    for (const s of segs) {
      if (s.length < 2) continue;
      ctx.strokeStyle = s === c.trail ? "#d62839" : "rgba(47,102,144,0.45)"; ctx.beginPath();
      s.forEach((p, i) => (i ? ctx.lineTo(X(p[k]), Z(-p[2])) : ctx.moveTo(X(p[k]), Z(-p[2]))));
      ctx.stroke();
    }
    this.caption(W);
  }

  /** What the horizontal axis is, top right on a white box (clear of the tick labels). */
  caption(W) {
    const ctx = this.canvas.getContext("2d"), text = this.axis === 0 ? "x north (m) →" : "y east (m) →";
    const w = ctx.measureText(text).width + 6;
    ctx.fillStyle = "rgba(255,255,255,0.85)"; ctx.fillRect(W - w - 4, 1, w, 13);
    ctx.fillStyle = "#1a1a1a"; this.text(text, W - w - 1, 11);
  }

  /** Draws a label (10 px) with its baseline at y; keeps its box in `labels` (for tests). */
  text(t, x, y) {
    const ctx = this.canvas.getContext("2d");
    ctx.fillText(t, x, y);
    this.labels.push({ text: t, x, y: y - 9, w: ctx.measureText(t).width, h: 11 });
  }
}
