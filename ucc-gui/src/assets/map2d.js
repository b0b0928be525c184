// The map: top view, x north up, y east right, in CSS pixels on a canvas sized for the
// screen's device pixel ratio (sharp on HiDPI screens).
import { bounds, centroid, fitView, niceStep, splitGeometry, wheelFactor, zoomAt, COLORS, VICTIM_COLOR, WALL_COLOR } from "./logic.js";

// Element sizes (CSS px, clientWidth × clientHeight), kept up to date by a ResizeObserver.
// Reading clientWidth while drawing a frame makes the browser lay the page out first: with
// 1000 UAVs in the list that took 35 ms a frame. A resize fires "ucc-resize" on window.
const sizes = new WeakMap();
let observer = null;

/** [clientWidth, clientHeight] of `el`, without a layout in the frame (see above). */
export function boxSize(el) {
  const known = sizes.get(el);
  if (known) return known;
  const size = [el.clientWidth, el.clientHeight];
  if (typeof ResizeObserver === "undefined") return size;
  sizes.set(el, size);
  if (!observer) {
    observer = new ResizeObserver((entries) => {
      for (const e of entries) sizes.set(e.target, [e.target.clientWidth, e.target.clientHeight]);
      window.dispatchEvent(new Event("ucc-resize"));
    });
  }
  observer.observe(el);
  return size;
}

/** Sizes a canvas's backing store to its CSS size × devicePixelRatio; returns [w, h] in CSS px. */
export function sizeCanvas(canvas) {
  const dpr = window.devicePixelRatio || 1;
  const [cw, ch] = boxSize(canvas);
  const w = Math.max(1, cw), h = Math.max(1, ch);
  const bw = Math.round(w * dpr), bh = Math.round(h * dpr);
  if (canvas.width !== bw || canvas.height !== bh) { canvas.width = bw; canvas.height = bh; }
  canvas.getContext("2d").setTransform(dpr, 0, 0, dpr, 0, 0);
  return [w, h];
}

/** Every point of a trail (or of many), for `bounds`. */
const eachOf = (lists) => (visit) => { for (const l of lists) for (const p of l) visit(p[0], p[1]); };

export class Map2d {
  constructor(canvas, store) {
    this.canvas = canvas; this.ctx = canvas.getContext("2d"); this.store = store;
    this.view = { cx: 0, cy: 0, scale: 20 }; this.fitted = false; this.geometry = null;
    this.layer = null; // a scenario's things: under(ctx, map), over(ctx, map), points() (scenario.js)
    this.w = 1; this.h = 1;
  }

  toScreen(x, y) { const v = this.view; return [this.w / 2 + (y - v.cy) * v.scale, this.h / 2 - (x - v.cx) * v.scale]; }
  toWorld(sx, sy) { const v = this.view; return [v.cx - (sy - this.h / 2) / v.scale, v.cy + (sx - this.w / 2) / v.scale]; }

  /** The part of the world shown, widened by `margin` of its size on each side:
   * [x0, x1, y0, y1] (the hub sends full detail only for the UAVs in it). */
  viewRect(margin = 0.25) {
    const [x0, y0] = this.toWorld(0, this.h), [x1, y1] = this.toWorld(this.w, 0);
    const mx = (x1 - x0) * margin, my = (y1 - y0) * margin;
    return [x0 - mx, x1 + mx, y0 - my, y1 + my];
  }

  fit() {
    [this.w, this.h] = sizeCanvas(this.canvas);
    const lists = [];
    if (this.geometry) for (const f of this.geometry) lists.push(f.outline);
    for (const c of this.store.uavs.values()) {
      lists.push(c.trail);
      lists.push(c.info.missions.filter((m) => m.kind === "GotoXyz").map((m) => [m.x, m.y]));
      if (c.live && c.live.position) lists.push([c.live.position]);
    }
    if (this.layer && this.layer.show) lists.push(this.layer.state.points());
    Object.assign(this.view, fitView(bounds(eachOf(lists)), this.w, this.h));
    this.fitted = true;
  }

  wheel(deltaY, deltaMode, sx, sy) {
    const [wx, wy] = this.toWorld(sx, sy);
    Object.assign(this.view, zoomAt(this.view, wheelFactor(deltaY, deltaMode), wx, wy));
  }

  path(points, color, width, step = 1) {
    if (points.length < 2) return;
    const ctx = this.ctx;
    ctx.strokeStyle = color; ctx.lineWidth = width; ctx.beginPath();
    let [sx, sy] = this.toScreen(points[0][0], points[0][1]); ctx.moveTo(sx, sy);
    for (let i = step; i < points.length; i += step) { [sx, sy] = this.toScreen(points[i][0], points[i][1]); ctx.lineTo(sx, sy); }
    const last = points[points.length - 1]; [sx, sy] = this.toScreen(last[0], last[1]); ctx.lineTo(sx, sy);
    ctx.stroke();
  }

  addPath(path, points, step = 1) {
    if (points.length < 2) return;
    let [sx, sy] = this.toScreen(points[0][0], points[0][1]); path.moveTo(sx, sy);
    for (let i = step; i < points.length; i += step) { [sx, sy] = this.toScreen(points[i][0], points[i][1]); path.lineTo(sx, sy); }
    const last = points[points.length - 1]; [sx, sy] = this.toScreen(last[0], last[1]); path.lineTo(sx, sy);
  }

  /** A triangle pointing along `yaw` (screen: north up, east right) into `path`. */
  triangle(path, px, py, yaw) {
    const c = Math.cos(yaw), s = Math.sin(yaw);
    const pt = (x, y) => [px + x * c - y * s, py + x * s + y * c];
    const [a, b, d] = [pt(0, -10), pt(6, 7), pt(-6, 7)];
    path.moveTo(a[0], a[1]); path.lineTo(b[0], b[1]); path.lineTo(d[0], d[1]); path.closePath();
  }

  waypoints(u, color) {
    const ctx = this.ctx;
    u.missions.forEach((m, i) => {
      if (m.kind !== "GotoXyz") return;
      const [sx, sy] = this.toScreen(m.x, m.y);
      ctx.strokeStyle = color; ctx.lineWidth = i === u.active ? 3 : 1.5;
      ctx.strokeRect(sx - 5, sy - 5, 10, 10);
      if (i === u.active) { ctx.fillStyle = color; ctx.fillRect(sx - 3, sy - 3, 6, 6); }
      ctx.fillStyle = "#1a1a1a"; ctx.fillText(String(i + 1), sx + 7, sy - 6);
    });
  }

  /** The selected UAV, on top: overlay, trail, waypoints, laser beams, sonar cones, name. */
  drawSelected(c, color, overlay) {
    const ctx = this.ctx, u = c.info, l = c.live;
    if (overlay) { ctx.globalAlpha = 0.35; for (const p of c.past) this.path(p, color, 1.5); ctx.globalAlpha = 1; }
    this.path(c.trail, color, 2.5);
    this.waypoints(u, color);
    if (!l || !l.position) return;
    const [px, py] = this.toScreen(l.position[0], l.position[1]);
    const yaw = l.attitude ? l.attitude[2] : 0;
    if (l.laser) {
      ctx.strokeStyle = "rgba(214,40,57,0.3)"; ctx.lineWidth = 1; ctx.beginPath();
      const n = l.laser.ranges.length;
      for (let i = 0; i < n; i++) {
        const r = l.laser.ranges[i]; if (r === null) continue;
        const a = yaw + l.laser.fov / 2 - i * l.laser.resolution;
        const [ex, ey] = this.toScreen(l.position[0] + r * Math.cos(a), l.position[1] + r * Math.sin(a));
        ctx.moveTo(px, py); ctx.lineTo(ex, ey);
      }
      ctx.stroke();
    }
    if (l.sonars) {
      ctx.fillStyle = "rgba(27,122,110,0.18)";
      l.sonars.forEach((r, i) => {
        if (r === null) return;
        const a = yaw + i * Math.PI / 4, half = 0.26; // 8 sonars, 45° apart, ~30° cones
        ctx.beginPath(); ctx.moveTo(px, py);
        const sa = Math.atan2(-Math.cos(a), Math.sin(a));
        ctx.arc(px, py, Math.min(r * this.view.scale, 1e5), sa - half, sa + half); ctx.closePath(); ctx.fill();
      });
    }
    const body = new Path2D(); this.triangle(body, px, py, yaw);
    ctx.fillStyle = color; ctx.fill(body); ctx.strokeStyle = "#000"; ctx.lineWidth = 1.5; ctx.stroke(body);
    ctx.fillStyle = "#1a1a1a"; ctx.fillText(u.name, px + 9, py + 4);
  }

  draw(selected, overlay) {
    [this.w, this.h] = sizeCanvas(this.canvas);
    if (!this.fitted) this.fit();
    const ctx = this.ctx, W = this.w, H = this.h, uavs = this.store.uavs;
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, W, H);
    // Grid at a nice step: a few dozen lines at any zoom.
    const step = niceStep(this.view.scale, 40);
    ctx.strokeStyle = "#e3e6ef"; ctx.lineWidth = 1; ctx.beginPath();
    const [wx0, wy0] = this.toWorld(0, H), [wx1, wy1] = this.toWorld(W, 0);
    for (let x = Math.ceil(wx0 / step) * step; x <= wx1; x += step) { const [, sy] = this.toScreen(x, 0); ctx.moveTo(0, sy); ctx.lineTo(W, sy); }
    for (let y = Math.ceil(wy0 / step) * step; y <= wy1; y += step) { const [sx] = this.toScreen(0, y); ctx.moveTo(sx, 0); ctx.lineTo(sx, H); }
    ctx.stroke();
    if (this.layer) this.layer.under(ctx, this);
    if (this.geometry) {
      // What stands at the flown heights (not the floor, not the ceiling), labelled with its height.
      let low = Infinity, high = -Infinity;
      const seen = (z) => { if (z < low) low = z; if (z > high) high = z; };
      for (const c of uavs.values()) {
        for (const m of c.info.missions) if (m.kind === "GotoXyz") seen(m.z);
        if (c.live && c.live.position) seen(c.live.position[2]);
      }
      if (low > high) { low = -3; high = -0.5; }
      // A scenario is seen from above: everything standing on the ground, half see-through
      // over its heat map.
      const scene = this.layer && this.layer.show && this.layer.state.fixed;
      if (scene) high = Math.max(high, -0.05);
      const { solids, victims } = splitGeometry(this.geometry);
      const polygon = (f) => {
        ctx.beginPath();
        f.outline.forEach((p, i) => { const [sx, sy] = this.toScreen(p[0], p[1]); i ? ctx.lineTo(sx, sy) : ctx.moveTo(sx, sy); });
        ctx.closePath(); ctx.fill();
      };
      ctx.fillStyle = WALL_COLOR; if (scene) ctx.globalAlpha = 0.6;
      for (const f of solids) if (f.z_min <= high && f.z_max >= low) polygon(f);
      ctx.globalAlpha = 1;
      // Victims lie on the floor: drawn at any height, with their names.
      ctx.fillStyle = VICTIM_COLOR; ctx.font = "11px sans-serif";
      for (const v of victims) {
        polygon(v);
        const [cx, cy] = centroid(v.outline), [sx, sy] = this.toScreen(cx, cy);
        ctx.fillText(v.victim, sx + 8, sy - 6);
      }
    } else {
      ctx.fillStyle = "#444";
      for (const c of uavs.values()) for (const h of c.hits) { const [sx, sy] = this.toScreen(h[0], h[1]); ctx.fillRect(sx - 1, sy - 1, 2, 2); }
    }
    if (this.layer) this.layer.over(ctx, this);
    const many = uavs.size > 50;
    ctx.font = "11px sans-serif";
    // Trails and UAVs are batched per colour: one path each, whatever the number of UAVs.
    const trails = COLORS.map(() => new Path2D()), bodies = COLORS.map(() => new Path2D());
    let k = 0, sel = null;
    for (const c of uavs.values()) {
      const ci = k++ % COLORS.length, color = COLORS[ci], u = c.info, isSel = u.id === selected;
      if (isSel) { sel = { c, color }; continue; }
      if (overlay && !many) { ctx.globalAlpha = 0.35; for (const p of c.past) this.path(p, color, 1.5); ctx.globalAlpha = 1; }
      this.addPath(trails[ci], c.trail, many ? Math.max(1, c.trail.length >> 6) : 1);
      if (!many) this.waypoints(u, color);
      const l = c.live;
      if (!l || !l.position) continue;
      const [px, py] = this.toScreen(l.position[0], l.position[1]);
      if (px < -20 || py < -20 || px > W + 20 || py > H + 20) continue;
      this.triangle(bodies[ci], px, py, l.attitude ? l.attitude[2] : 0);
      if (!many) { ctx.fillStyle = "#1a1a1a"; ctx.fillText(u.name, px + 9, py + 4); }
    }
    ctx.lineWidth = 1.5;
    COLORS.forEach((color, i) => { ctx.strokeStyle = color; ctx.stroke(trails[i]); ctx.fillStyle = color; ctx.fill(bodies[i]); });
    if (sel) this.drawSelected(sel.c, sel.color, overlay);
    // Scale bar.
    ctx.fillStyle = "#1a1a1a"; ctx.fillRect(10, H - 14, step * this.view.scale, 3);
    ctx.fillText(`${step} m`, 14 + step * this.view.scale, H - 10);
  }
}
