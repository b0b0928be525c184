// The scenario shown on the page (issue #22, docs/scenarios.md): its state merged from the
// hub's updates, the text of its figures, and its things drawn on the map (the coverage heat
// map, the search area, victims found or not, targets, the fire, pads, the relay's
// endpoints and link). The pure part (ScenarioState, levelColor, decodeGrid,
// applyGridChanges, linkSegments, formatMetric) is unit-tested with
// `node --test ucc-gui/tests/js/`; the drawing takes the map's canvas context.
import { VICTIM_COLOR } from "./logic.js";
import { boxSize } from "./map2d.js";

/** The highest heat level of a coverage cell (the hub's LEVELS): level k ≥ 1 means seen
 * for at least 2^(k-1) periods; 0 never. */
export const LEVELS = 9;
export const FOUND_COLOR = "#1b7a6e";
export const TARGET_COLOR = "#d62839";
export const FIRE_COLOR = "#c2410c";
export const LINK_UP = "#2e8b57";
export const LINK_DOWN = "#b00d1a";

/** The colour of a heat level, [r, g, b, a]: pale red never seen, then greener the longer
 * (the pictures' colours, ucc-client's scenario/picture.rs). */
export function levelColor(level) {
  if (!(level > 0)) return [255, 225, 225, 170];
  const f = Math.sqrt(Math.min(level, LEVELS) / LEVELS);
  return [Math.round(210 - 150 * f), Math.round(240 - 80 * f), Math.round(210 - 150 * f), 190];
}

/** The whole grid as the hub sends it once (one digit a cell) → levels. */
export function decodeGrid(text) {
  const levels = new Uint8Array(text.length);
  for (let k = 0; k < text.length; k++) {
    const l = text.charCodeAt(k) - 48;
    levels[k] = l >= 0 && l <= LEVELS ? l : 0;
  }
  return levels;
}

/** Applies the changes the hub sends, `[index, level, index, level, …]`, to `levels` in
 * place; indices outside are ignored. Returns the indices changed. */
export function applyGridChanges(levels, flat) {
  const changed = [];
  for (let k = 0; k + 1 < flat.length; k += 2) {
    const i = flat[k], l = flat[k + 1];
    if (Number.isInteger(i) && i >= 0 && i < levels.length && l >= 0 && l <= LEVELS) { levels[i] = l; changed.push(i); }
  }
  return changed;
}

/** The link strip from its changes `[[time, up], …]` up to `until`: [{from, to, up}]. */
export function linkSegments(changes, until) {
  const out = [];
  for (let k = 0; k < changes.length; k++) {
    const [from, up] = changes[k];
    const to = k + 1 < changes.length ? changes[k + 1][0] : Math.max(until, from);
    if (to > from || k + 1 === changes.length) out.push({ from, to, up });
  }
  return out;
}

/** What each metric is called on the page. */
export const METRIC_LABELS = {
  time_s: "time", crashes: "crashes", battery_used: "batteries used", recharges: "recharges",
  coverage_pct: "area covered", victims_found: "victims found", victims_total: "victims in all",
  first_find_s: "first find", all_found_s: "all found", link_pct: "link up", longest_outage_s: "longest outage",
  target_seen_pct: "target in view", tracking_error_m: "tracking error", tracking_error_max_m: "largest tracking error",
  update_interval_s: "perimeter update interval", update_interval_max_s: "longest update interval",
  deliveries: "deliveries", delivery_time_s: "delivered at", drop_error_m: "drop error",
};

/** A metric's value as text with its unit (by the name's suffix); "–" when not measured. */
export function formatMetric(name, value) {
  if (value === null || value === undefined || !Number.isFinite(value)) return "–";
  if (name.endsWith("_pct")) return `${value.toFixed(1)} %`;
  if (name.endsWith("_s")) return `${value.toFixed(1)} s`;
  if (name.endsWith("_m")) return `${value.toFixed(2)} m`;
  if (name === "battery_used") return value.toFixed(2);
  return Number.isInteger(value) ? String(value) : value.toFixed(2);
}

/** The page's copy of the scenario, merged from the `scenario` part of the hub's updates. */
export class ScenarioState {
  constructor() {
    this.fixed = null; this.levels = new Uint8Array(0); this.gridVersion = 0; this.changedCells = null;
    this.victims = []; this.link = []; this.rows = []; this.metrics = []; this.targets = [];
    this.status = null; this.name = ""; this.iteration = 0; this.iterations = 0; this.seed = "";
    this.speed = "1"; this.time = 0; this.error = null; this.fire_radius = null; this.link_up = null; this.columns = [];
    this.uavs = [];
  }

  /** Merges one update's `scenario`; returns what changed: {fixed, grid, rows, victims}. */
  merge(s) {
    const changed = { fixed: false, grid: false, rows: false, victims: false };
    // `changedCells`: the cells changed since the heat map was last painted; null: all.
    if (s.fixed) { this.fixed = s.fixed; this.rows = []; this.levels = new Uint8Array(0); this.changedCells = null; changed.fixed = changed.rows = changed.grid = true; }
    if (s.reset) { this.link = []; this.victims = []; changed.victims = true; }
    if (typeof s.grid_full === "string") { this.levels = decodeGrid(s.grid_full); this.changedCells = null; changed.grid = true; }
    if (Array.isArray(s.grid)) {
      const cells = applyGridChanges(this.levels, s.grid);
      if (this.changedCells) for (const k of cells) this.changedCells.push(k);
      changed.grid = true;
    }
    if (s.victims) { this.victims = s.victims; changed.victims = true; }
    if (s.link) for (const l of s.link) this.link.push(l);
    if (s.rows) { for (const r of s.rows) this.rows.push(r); changed.rows = true; }
    for (const k of ["name", "status", "error", "iteration", "iterations", "seed", "speed", "time", "metrics", "targets", "fire_radius", "link_up", "columns", "uavs"]) {
      if (s[k] !== undefined) this[k] = s[k];
    }
    if (changed.grid) this.gridVersion++;
    return changed;
  }

  /** The figure of `name` now, or null. */
  metric(name) {
    const m = this.metrics.find((x) => x[0] === name);
    return m ? m[1] : null;
  }

  /** Points the map's "fit" should show: the area, pads, endpoints, the fire. */
  points() {
    const f = this.fixed, pts = [];
    if (!f) return pts;
    if (f.grid) pts.push(...f.grid.area);
    for (const p of f.pads || []) pts.push(p.pad.at);
    if (f.endpoints) pts.push(...f.endpoints);
    if (f.fire) { const r = this.fire_radius || f.fire.radius, [x, y] = f.fire.center; pts.push([x - r, y - r], [x + r, y + r]); }
    for (const w of f.waypoints || []) pts.push(w);
    return pts;
  }
}

/** Draws a scenario's things on the map (Map2d: `under` before the walls, `over` after). */
export class ScenarioLayer {
  constructor(state) { this.state = state; this.image = null; this.pixels = null; this.drawn = -1; this.show = true; }

  /** The heat map as an image of one pixel a cell, north up: updated cell by cell. */
  heat() {
    const s = this.state, g = s.fixed && s.fixed.grid;
    if (!g || s.levels.length !== g.shape[0] * g.shape[1]) return null;
    const [nx, ny] = g.shape;
    if (!this.image || this.image.width !== ny || this.image.height !== nx) {
      this.image = document.createElement("canvas"); this.image.width = ny; this.image.height = nx;
      this.pixels = this.image.getContext("2d").createImageData(ny, nx); this.drawn = -1;
    }
    if (this.drawn !== s.gridVersion) {
      const px = this.pixels.data, paint = (k) => {
        const i = Math.floor(k / ny), j = k % ny, o = ((nx - 1 - i) * ny + j) * 4, c = levelColor(s.levels[k]);
        px[o] = c[0]; px[o + 1] = c[1]; px[o + 2] = c[2]; px[o + 3] = c[3];
      };
      if (s.changedCells && this.drawn >= 0) for (const k of s.changedCells) paint(k);
      else for (let k = 0; k < s.levels.length; k++) paint(k);
      s.changedCells = [];
      this.image.getContext("2d").putImageData(this.pixels, 0, 0);
      this.drawn = s.gridVersion;
    }
    return this.image;
  }

  under(ctx, map) {
    const f = this.state.fixed;
    if (!this.show || !f || !f.grid) return;
    const g = f.grid, img = this.heat();
    const [x0, y0] = g.origin, [nx, ny] = g.shape;
    const [l, t] = map.toScreen(x0 + nx * g.cell, y0), [r, b] = map.toScreen(x0, y0 + ny * g.cell);
    if (img) { ctx.save(); ctx.imageSmoothingEnabled = false; ctx.drawImage(img, l, t, r - l, b - t); ctx.restore(); }
    const [[ax0, ay0], [ax1, ay1]] = g.area, [al, at] = map.toScreen(ax1, ay0), [ar, ab] = map.toScreen(ax0, ay1);
    ctx.strokeStyle = "#1a1a1a"; ctx.lineWidth = 1; ctx.strokeRect(al, at, ar - al, ab - at);
  }

  over(ctx, map) {
    const s = this.state, f = s.fixed;
    if (!this.show || !f) return;
    const scale = map.view.scale;
    ctx.font = "11px sans-serif";
    const label = (text, sx, sy, color = "#1a1a1a") => { ctx.fillStyle = color; ctx.fillText(text, sx + 7, sy - 6); };
    // Pads: circles of their radius, named.
    for (const p of f.pads || []) {
      const [sx, sy] = map.toScreen(p.pad.at[0], p.pad.at[1]);
      ctx.strokeStyle = "#1769aa"; ctx.lineWidth = 2; ctx.setLineDash([4, 3]);
      ctx.beginPath(); ctx.arc(sx, sy, Math.max(4, p.pad.radius * scale), 0, 2 * Math.PI); ctx.stroke(); ctx.setLineDash([]);
      label(p.name, sx, sy, "#1769aa");
    }
    // The delivery's waypoints.
    if (f.waypoints && f.waypoints.length) map.path(f.waypoints, "rgba(23,105,170,0.5)", 1);
    // The relay: its endpoints, joined green while the link is up, red dashed while down.
    if (f.endpoints) {
      const [a, b] = f.endpoints.map((e) => map.toScreen(e[0], e[1]));
      const up = s.link_up === true;
      ctx.strokeStyle = up ? LINK_UP : LINK_DOWN; ctx.lineWidth = 2; ctx.setLineDash(up ? [] : [6, 4]);
      ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke(); ctx.setLineDash([]);
      [a, b].forEach(([sx, sy], i) => {
        ctx.fillStyle = "#1a1a1a"; ctx.fillRect(sx - 5, sy - 5, 10, 10);
        label(`endpoint ${"AB"[i]}`, sx, sy);
      });
    }
    // The fire: its perimeter now (solid) and at the start (dashed).
    if (f.fire) {
      const [sx, sy] = map.toScreen(f.fire.center[0], f.fire.center[1]);
      ctx.strokeStyle = FIRE_COLOR; ctx.lineWidth = 1; ctx.setLineDash([4, 4]);
      ctx.beginPath(); ctx.arc(sx, sy, f.fire.radius * scale, 0, 2 * Math.PI); ctx.stroke(); ctx.setLineDash([]);
      const r = s.fire_radius || f.fire.radius;
      ctx.lineWidth = 2.5; ctx.beginPath(); ctx.arc(sx, sy, r * scale, 0, 2 * Math.PI); ctx.stroke();
      label(`fire r = ${r.toFixed(1)} m`, sx + r * scale * 0.7, sy - r * scale * 0.7, FIRE_COLOR);
    }
    // Victims: found (green, filled) or not yet (magenta ring).
    for (const v of s.victims) {
      if (!v.at || v.at[0] === null) continue;
      const [sx, sy] = map.toScreen(v.at[0], v.at[1]), found = v.found !== null && v.found !== undefined;
      ctx.beginPath(); ctx.arc(sx, sy, Math.max(4, 0.5 * scale), 0, 2 * Math.PI);
      if (found) { ctx.fillStyle = FOUND_COLOR; ctx.fill(); } else { ctx.strokeStyle = VICTIM_COLOR; ctx.lineWidth = 2.5; ctx.stroke(); }
      label(found ? `${v.name} ✓ ${v.found.toFixed(0)} s` : v.name, sx, sy, found ? FOUND_COLOR : VICTIM_COLOR);
    }
    // Targets: red diamonds, named.
    (s.targets || []).forEach((t, i) => {
      if (t[0] === null) return;
      const [sx, sy] = map.toScreen(t[0], t[1]);
      ctx.fillStyle = TARGET_COLOR; ctx.beginPath();
      ctx.moveTo(sx, sy - 7); ctx.lineTo(sx + 7, sy); ctx.lineTo(sx, sy + 7); ctx.lineTo(sx - 7, sy); ctx.closePath(); ctx.fill();
      label((f.targets && f.targets[i]) || `target ${i + 1}`, sx, sy, TARGET_COLOR);
    });
  }

  /** The link over the iteration's time on a strip canvas: green up, red down. */
  strip(canvas, width) {
    const s = this.state, f = s.fixed, dpr = window.devicePixelRatio || 1, h = 14;
    canvas.width = Math.round(width * dpr); canvas.height = Math.round(h * dpr);
    canvas.style.width = width + "px"; canvas.style.height = h + "px";
    const ctx = canvas.getContext("2d"); ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = "#e3e6ef"; ctx.fillRect(0, 0, width, h);
    const limit = (f && f.time_limit) || 1, x = (t) => (t / limit) * width;
    for (const seg of linkSegments(s.link, s.time)) {
      ctx.fillStyle = seg.up ? LINK_UP : LINK_DOWN;
      ctx.fillRect(x(seg.from), 0, Math.max(1, x(seg.to) - x(seg.from)), h);
    }
  }
}

/** The scenario's controls (choose, start, stop, speed) and its panel (status, metrics,
 * link, results). `deps`: {$, el, send, q (the token's query), onGeometry(geometry|null)}
 * from the page. */
export class ScenarioPanel {
  constructor(deps) {
    Object.assign(this, deps);
    this.state = new ScenarioState(); this.layer = new ScenarioLayer(this.state); this.list = [];
    const $ = this.$;
    $("scenario-form").addEventListener("submit", (e) => {
      e.preventDefault();
      this.send({ op: "scenario_start", name: $("scenario-name").value, iterations: $("scenario-iterations").value, seed: $("scenario-seed").value, speed: $("scenario-speed").value });
    });
    $("scenario-stop").onclick = () => this.send({ op: "scenario_stop" });
    $("scenario-speed").onchange = () => { if (this.running()) this.send({ op: "scenario_speed", value: $("scenario-speed").value }); };
    $("scenario-name").onchange = () => this.about();
    $("scenario-csv").href = "/api/scenario/results.csv" + (this.q || "");
    $("scenario-show").onchange = () => { this.layer.show = $("scenario-show").checked; this.onGeometry(this.geometry()); };
  }

  running() { return this.state.status === "running" || this.state.status === "stopping"; }

  /** The scenario's map while it is shown, else null (the server's). */
  geometry() { return this.layer.show && this.state.fixed ? this.state.fixed.geometry : null; }

  /** The embedded scenarios, from the hello. */
  hello(list) {
    this.list = list;
    const sel = this.$("scenario-name"), v = sel.value;
    sel.replaceChildren(...list.map((s) => this.el("option", `${s.name} (${s.kind}, ${s.uavs} UAV${s.uavs === 1 ? "" : "s"})`, { value: s.name })));
    if (v) sel.value = v;
    this.about();
  }

  about() {
    const s = this.list.find((x) => x.name === this.$("scenario-name").value);
    this.$("scenario-about").textContent = s ? `${s.description} · map ${s.map} · up to ${s.time_limit} s · seed ${s.seed}` : "";
  }

  /** Merges an update's `scenario` and shows it; returns true (the map is to be drawn). */
  update(u) {
    const $ = this.$, el = this.el, s = this.state, changed = s.merge(u), f = s.fixed;
    if (changed.fixed) {
      this.onGeometry(this.geometry());
      $("scenario-title").textContent = f.name;
      $("scenario-link-box").hidden = !f.endpoints;
      $("scenario-results").replaceChildren(el("tr", null));
    }
    $("scenario-box").hidden = !f;
    if (!f) return true;
    const limit = f.time_limit;
    $("scenario-status").textContent = `${s.status}${s.error ? ": " + s.error : ""} · iteration ${s.iteration}/${s.iterations} · seed ${s.seed} · t = ${(s.time || 0).toFixed(1)} s of ${limit} s · speed ${s.speed === "max" ? "max" : "×" + s.speed}`;
    $("scenario-status").dataset.status = s.status;
    $("scenario-start").disabled = this.running();
    $("scenario-stop").disabled = !this.running();
    if (document.activeElement !== $("scenario-speed") && [...$("scenario-speed").options].some((o) => o.value === s.speed)) $("scenario-speed").value = s.speed;
    $("scenario-metrics").replaceChildren(...s.metrics.map(([name, v]) => {
      const tr = el("tr", null, { "data-metric": name });
      tr.append(el("th", METRIC_LABELS[name] || name), el("td", formatMetric(name, v)));
      return tr;
    }));
    if (f.endpoints) {
      $("scenario-link").textContent = s.link_up === null ? "–" : s.link_up ? "up" : "down";
      $("scenario-link").style.color = s.link_up ? LINK_UP : LINK_DOWN;
      const strip = $("scenario-strip");
      this.layer.strip(strip, Math.max(100, boxSize(strip.parentElement)[0] - 4));
    }
    if (changed.rows) {
      const head = el("tr", null);
      head.append(...["iteration", "seed", "ending", ...s.columns].map((c) => el("th", METRIC_LABELS[c] || c, { title: c })));
      const rows = s.rows.slice(-200).map((r) => {
        const tr = el("tr", null);
        tr.append(el("td", String(r.iteration)), el("td", r.seed), el("td", r.ending), ...r.values.map((v, i) => el("td", formatMetric(s.columns[i] || "", v))));
        return tr;
      });
      $("scenario-results").replaceChildren(head, ...rows);
      $("scenario-results-count").textContent = s.rows.length > 200 ? `the last 200 of ${s.rows.length}` : `${s.rows.length}`;
    }
    return true;
  }
}
