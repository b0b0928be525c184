// The page's logic without the DOM: numbers, bounds, zoom, decimation, colours, the state
// store. Unit-tested with `node --test ucc-gui/tests/js/` (no browser, no bundler).

/** Pixels per metre the map may zoom to (bounds of the wheel and of "fit"). */
export const SCALE_MIN = 1e-3;
export const SCALE_MAX = 2000;
/** Points kept per trail in the page; beyond it every other point is dropped. */
export const MAX_TRAIL = 4000;
/** Past iterations kept per UAV for the overlay (the hub bounds them too). */
export const MAX_PAST = 100;
/** Samples kept for the plots. */
export const MAX_HISTORY = 5000;
/** Laser hits kept per UAV (the map of a server without geometry). */
export const MAX_HITS = 20000;
/** Log lines kept (and shown at most): the newest; "Save log" downloads the server's (it
 * keeps more), and the complete log of a run is its log files. */
export const MAX_LOG = 2000;

/** Colours, chosen for ≥ 4.5:1 contrast on white (WCAG AA). */
export const WALL_COLOR = "#5c677d";
/** Victims on the map (the pictures' colour, ucc_client::picture::VICTIM_COLOUR). */
export const VICTIM_COLOR = "#d628c8";
export const WARN_COLOR = "#8a5300";
export const ERROR_COLOR = "#b00d1a";
export const COLORS = ["#d62839", "#2f6690", "#1b7a6e", "#b5651d", "#6a4c93", "#1769aa", "#4d7c0f", "#c2185b"];

export const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));

/**
 * The bounds of many points without spreading them into arguments (which throws a
 * RangeError beyond ~100k values): `{x0, x1, y0, y1}` or null when there is none.
 * `each(visit)` calls `visit(x, y)` for every point.
 */
/** The map's geometry as the page gets it, split: solids (drawn at the flown heights) and
 * victims (entries with a `victim` name; drawn at any height, named). */
export function splitGeometry(geometry) {
  const solids = [], victims = [];
  for (const f of geometry || []) (typeof f.victim === "string" ? victims : solids).push(f);
  return { solids, victims };
}

/** The centre of a polygon's corners, [x, y]: where a victim's name goes. */
export function centroid(outline) {
  let x = 0, y = 0;
  for (const p of outline) { x += p[0]; y += p[1]; }
  return outline.length ? [x / outline.length, y / outline.length] : [0, 0];
}

export function bounds(each) {
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  each((x, y) => {
    if (!Number.isFinite(x) || !Number.isFinite(y)) return;
    if (x < x0) x0 = x;
    if (x > x1) x1 = x;
    if (y < y0) y0 = y;
    if (y > y1) y1 = y;
  });
  return x0 <= x1 ? { x0, x1, y0, y1 } : null;
}

/** Minimum and maximum of an array of numbers (nulls skipped), or null. */
export function range(values) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) {
    if (v === null || v === undefined || !Number.isFinite(v)) continue;
    if (v < lo) lo = v;
    if (v > hi) hi = v;
  }
  return lo <= hi ? [lo, hi] : null;
}

/**
 * The view that shows `b` (world x north up, y east right) in a `width`×`height` area:
 * centre and pixels per metre, within the zoom limits.
 */
export function fitView(b, width, height) {
  if (!b) b = { x0: -10, x1: 10, y0: -10, y1: 10 };
  const scale = clamp(
    Math.min(width / Math.max(b.y1 - b.y0 + 2, 4), height / Math.max(b.x1 - b.x0 + 2, 4)),
    SCALE_MIN,
    SCALE_MAX,
  );
  return { cx: (b.x0 + b.x1) / 2, cy: (b.y0 + b.y1) / 2, scale };
}

/**
 * The zoom factor of one wheel event: by the distance scrolled (pixels; lines and pages
 * converted), not by the number of events, and at most ×2 per event.
 */
export function wheelFactor(deltaY, deltaMode = 0) {
  const px = deltaY * (deltaMode === 1 ? 16 : deltaMode === 2 ? 400 : 1);
  return clamp(Math.exp(-px * 0.002), 0.5, 2);
}

/** The zoom after a wheel event at world point (wx, wy): scale clamped, the point kept. */
export function zoomAt(view, factor, wx, wy) {
  const scale = clamp(view.scale * factor, SCALE_MIN, SCALE_MAX);
  const f = scale / view.scale;
  return { cx: wx + (view.cx - wx) / f, cy: wy + (view.cy - wy) / f, scale };
}

/**
 * A "nice" grid step (1, 2 or 5 × 10^k metres) at least `minPx` pixels wide at `scale`
 * pixels per metre, so that a view has at most a few dozen grid lines at any zoom.
 */
export function niceStep(scale, minPx = 40) {
  const raw = minPx / scale;
  const p = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

/** Ticks from `lo` to `hi`, about `n` of them, at a nice step. */
export function ticks(lo, hi, n = 5) {
  if (!(hi > lo)) return [lo];
  const step = niceStep(1, (hi - lo) / n);
  const out = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9 && out.length < 100; t += step) out.push(+t.toFixed(10));
  return out;
}

/**
 * Appends `items` to `list` in place and keeps it at most `max` long by dropping every
 * other point of the older half (a long trail stays whole, only coarser). Returns list.
 */
export function appendDecimated(list, items, max) {
  for (let i = 0; i < items.length; i++) list.push(items[i]);
  if (list.length > max) {
    const half = list.length >> 1;
    let w = 0;
    for (let i = 0; i < half; i += 2) list[w++] = list[i];
    for (let i = half; i < list.length; i++) list[w++] = list[i];
    list.length = w;
  }
  return list;
}

/** Appends in place and drops the oldest beyond `max`. Returns list. */
export function appendCapped(list, items, max) {
  for (let i = 0; i < items.length; i++) list.push(items[i]);
  if (list.length > max) list.splice(0, list.length - max);
  return list;
}

/** WCAG contrast ratio of two `#rrggbb` colours. */
export function contrast(a, b) {
  const lum = (hex) => {
    const c = hex.match(/[0-9a-f]{2}/gi).map((h) => parseInt(h, 16) / 255)
      .map((v) => (v <= 0.03928 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4));
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
  };
  const [x, y] = [lum(a), lum(b)].sort((p, q) => q - p);
  return (x + 0.05) / (y + 0.05);
}

/**
 * The page's copy of the state, merged from the hub's updates, which carry only what
 * changed (and, for a UAV outside the map's view, a `live` summary with `summary: true`,
 * docs/gui.md): a UAV's `info` fields when they change, its `live` state when there is a new
 * sample, its `files` when the list changes, new trail/plot/overlay points, and the ids
 * of removed UAVs.
 */
export class Store {
  constructor() {
    this.uavs = new Map(); // id -> {info, live, files, filesVersion, trail, past, history, hits}
    this.server = null;
    this.log = [];
  }

  /** Merges one update; returns what changed: {uavs, files, log, server}. */
  merge(m) {
    const changed = { info: false, files: false, log: m.log ? m.log.length > 0 : false, server: false };
    if (m.server) {
      changed.server = JSON.stringify(m.server) !== JSON.stringify(this.server);
      this.server = m.server;
    }
    for (const id of m.removed || []) { if (this.uavs.delete(id)) changed.info = true; }
    for (const u of m.uavs || []) {
      let c = this.uavs.get(u.id);
      if (!c) {
        c = { info: { id: u.id, missions: [] }, live: null, files: [], filesVersion: 0, trail: [], past: [], history: [], hits: [] };
        this.uavs.set(u.id, c);
        changed.info = true;
      }
      if (u.info) { c.info = Object.assign({ id: u.id }, u.info); changed.info = true; }
      if (u.live !== undefined) c.live = u.live;
      if (u.files) { c.files = u.files; c.filesVersion++; changed.files = true; }
      if (u.trail_reset) c.trail = [];
      if (u.history_reset) c.history = [];
      if (u.past_reset) c.past = [];
      if (u.trail) appendDecimated(c.trail, u.trail, MAX_TRAIL);
      if (u.history) appendDecimated(c.history, u.history, MAX_HISTORY);
      if (u.past) for (const p of u.past) { const t = []; appendDecimated(t, p, MAX_TRAIL); c.past.push(t); }
      if (c.past.length > MAX_PAST) c.past.splice(0, c.past.length - MAX_PAST);
      if (u.hits) appendCapped(c.hits, u.hits, MAX_HITS);
    }
    if (m.log) appendCapped(this.log, m.log, MAX_LOG);
    return changed;
  }
}
