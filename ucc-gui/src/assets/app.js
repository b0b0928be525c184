// The UAV Control Center page: renders what the Rust side sends, sends what the user asks.
// The Rust side owns the state and checks every request; this page keeps only what it draws.
"use strict";
const $ = (id) => document.getElementById(id);
const token = new URLSearchParams(location.search).get("token");
const q = token ? "?token=" + encodeURIComponent(token) : "";
const uavs = new Map(); // id -> {info, trail, past, history, hits}
let selected = null, geometry = null, ws = null, logLines = [], logDirty = false;
let view = { cx: 0, cy: 0, scale: 20, fitted: false };
let dirty = true, optionsShown = null; // the UAV whose logging options the form shows
window.uccFrameTimes = []; // draw time of each frame, ms (the benchmark reads it)
window.uccUpdates = 0; // state updates received

function send(obj) { if (ws && ws.readyState === 1) ws.send(JSON.stringify(obj)); }
function showError(message) {
  const e = $("error"); e.textContent = message; e.hidden = false;
  clearTimeout(showError.t); showError.t = setTimeout(() => { e.hidden = true; }, 8000);
}
function needSelected() { if (selected === null) { showError("create or select a UAV first"); return false; } return true; }

function connect() {
  ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws" + q);
  ws.onopen = () => { $("conn").textContent = "live"; };
  ws.onclose = () => { $("conn").textContent = "disconnected — reload the page"; };
  ws.onmessage = (ev) => {
    const m = JSON.parse(ev.data);
    if (m.type === "hello") hello(m);
    else if (m.type === "state") update(m);
    else if (m.type === "error") showError(m.message);
    else if (m.type === "created") select(m.uav);
  };
}

function hello(m) {
  geometry = m.geometry;
  $("agent-type").innerHTML = m.agents.map((a) => `<option>${a}</option>`).join("");
  $("robots").innerHTML = m.robots.map((r) => `<option value="${r}">`).join("");
  $("speed-row").hidden = !m.local;
  view.fitted = false; dirty = true;
}

function update(m) {
  window.uccUpdates++;
  const s = m.server;
  $("server-info").textContent = `${s.local ? "local server" : "server"} ${s.addr}${s.map ? " · map " + s.map : ""}`;
  if (document.activeElement !== $("speed")) $("speed").value = s.speed;
  $("speed-row").hidden = !s.local;
  if (!s.local && geometry) { geometry = null; view.fitted = false; } // switched to another server
  $("pause").textContent = s.paused ? "Resume" : "Pause";
  $("pause").dataset.paused = s.paused;
  const seen = new Set();
  for (const u of m.uavs) {
    seen.add(u.id);
    let c = uavs.get(u.id);
    if (!c) { c = { trail: [], past: [], history: [], hits: [] }; uavs.set(u.id, c); }
    if (u.trail_reset) c.trail = [];
    if (u.history_reset) c.history = [];
    if (u.past_reset) c.past = [];
    c.trail.push(...u.trail); c.history.push(...u.history); c.past.push(...u.past); c.hits.push(...u.hits);
    c.info = u;
  }
  for (const id of [...uavs.keys()]) if (!seen.has(id)) uavs.delete(id);
  if (selected !== null && !uavs.has(selected)) selected = null;
  if (selected === null && uavs.size) select(uavs.keys().next().value);
  for (const l of m.log) logLines.push(l);
  if (logLines.length > 20000) logLines = logLines.slice(-20000);
  if (m.log.length) logDirty = true;
  panels();
  dirty = true;
}

function select(id) {
  selected = id; send({ op: "select", uav: id });
  optionsShown = null;
  panels(); dirty = true;
}

const fmt = (v, d = 2) => (v === null || v === undefined ? "–" : v.toFixed(d));
const fmt3 = (a, d = 2) => (a ? a.map((v) => fmt(v, d)).join(",") : "–");

function panels() {
  const list = $("uav-list");
  const html = [...uavs.values()].map((c) => {
    const u = c.info;
    return `<li data-id="${u.id}" class="${u.id === selected ? "sel" : ""}">${u.name} · ${u.robot} · ${u.agent} · ${u.status}${u.status === "running" ? " " + u.iteration + "/" + u.iterations : ""}</li>`;
  }).join("");
  if (list.innerHTML !== html) list.innerHTML = html;
  const opts = '<option value="">all UAVs</option>' + [...uavs.values()].map((c) => `<option value="${c.info.id}">${c.info.name}</option>`).join("");
  const lu = $("log-uav"); if (lu.dataset.html !== opts) { const v = lu.value; lu.innerHTML = opts; lu.dataset.html = opts; lu.value = v; }
  const c = selected !== null ? uavs.get(selected) : null;
  if (!c) { $("title").textContent = "UAV Control Center"; return; }
  const u = c.info, l = u.live;
  if (optionsShown !== u.id) {
    optionsShown = u.id;
    $("prefix").value = u.prefix; $("pictures").value = u.pictures; $("autosave").checked = u.autosave;
  }
  $("title").textContent = `UAV Control Center — ${u.name}: ${u.robot}, agent ${u.agent}`;
  $("mission-owner").textContent = "of " + u.name;
  const ml = u.missions.map((m, i) => `<li class="${i === u.active ? "active" : ""}">${i === u.active ? "▶ " : ""}${m.text} <button data-remove="${i}">×</button></li>`).join("");
  if ($("mission-list").innerHTML !== ml) $("mission-list").innerHTML = ml;
  $("iteration-counter").textContent = String(u.iteration);
  $("iteration-total").textContent = String(u.iterations);
  $("run-status").textContent = u.status + (u.error ? ": " + u.error : "");
  $("run-status").dataset.status = u.status;
  $("uav-position").textContent = l && l.position ? fmt3(l.position) : "";
  $("uav-velocity").textContent = l ? fmt3(l.velocity) + " m/s" : "";
  $("uav-attitude").textContent = l ? fmt3(l.attitude, 3) + " rad" : "";
  $("uav-battery").textContent = l && l.battery ? `${(l.battery.level * 100).toFixed(0)}% (${l.battery.remaining} s)` : "";
  $("uav-time").textContent = l ? fmt(l.time) + " s" : "";
  let sensors = "";
  if (l) {
    if (l.sonars) sensors += "sonars " + l.sonars.map((s) => fmt(s)).join(" ") + "\n";
    if (l.altitude !== undefined) sensors += `altitude ${fmt(l.altitude)} · free above ${fmt(l.free_above)} · below ${fmt(l.free_below)}\n`;
    if (l.laser) sensors += `laser ${l.laser.ranges.length} beams, min ${fmt(Math.min(...l.laser.ranges.filter((r) => r !== null)))} m\n`;
    if (l.command) sensors += "command fwd,right,up,yaw " + l.command.map((v) => fmt(v, 1)).join(",") + "\n";
  }
  $("sensors").textContent = sensors;
  const files = u.files.map((f) => `<a href="/api/files/${u.id}/${f.index}${q}" download>${f.name}</a>`).join("");
  if ($("files").innerHTML !== files) $("files").innerHTML = files;
}

// ---- map: top view, x north up, y east right ----
const map = $("map"), ctx = map.getContext("2d");
function toScreen(x, y) { return [map.width / 2 + (y - view.cy) * view.scale, map.height / 2 - (x - view.cx) * view.scale]; }
function toWorld(sx, sy) { return [view.cx - (sy - map.height / 2) / view.scale, view.cy + (sx - map.width / 2) / view.scale]; }
const COLORS = ["#e63946", "#457b9d", "#2a9d8f", "#f4a261", "#6a4c93", "#1982c4", "#8ac926", "#ff595e"];

function fit() {
  let xs = [], ys = [];
  if (geometry) for (const f of geometry) for (const p of f.outline) { xs.push(p[0]); ys.push(p[1]); }
  for (const c of uavs.values()) {
    for (const p of c.trail) { xs.push(p[0]); ys.push(p[1]); }
    for (const m of c.info.missions) if (m.kind === "GotoXyz") { xs.push(m.x); ys.push(m.y); }
  }
  if (!xs.length) { xs = [-10, 10]; ys = [-10, 10]; }
  const x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
  view.cx = (x0 + x1) / 2; view.cy = (y0 + y1) / 2;
  view.scale = Math.min(map.width / Math.max(y1 - y0 + 2, 4), map.height / Math.max(x1 - x0 + 2, 4));
  view.fitted = true; dirty = true;
}

function path(points, color, width) {
  if (points.length < 2) return;
  ctx.strokeStyle = color; ctx.lineWidth = width; ctx.beginPath();
  let [sx, sy] = toScreen(points[0][0], points[0][1]); ctx.moveTo(sx, sy);
  for (let i = 1; i < points.length; i++) { [sx, sy] = toScreen(points[i][0], points[i][1]); ctx.lineTo(sx, sy); }
  ctx.stroke();
}

function drawMap() {
  const w = map.clientWidth | 0;
  if (w > 0 && map.width !== w) { map.width = w; map.height = Math.round(w * 0.7); }
  if (!view.fitted) fit();
  ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, map.width, map.height);
  // grid, 1 m or 10 m
  const step = view.scale > 15 ? 1 : view.scale > 2 ? 10 : 100;
  ctx.strokeStyle = "#eef"; ctx.lineWidth = 1; ctx.beginPath();
  const [wx0, wy0] = toWorld(0, map.height), [wx1, wy1] = toWorld(map.width, 0);
  for (let x = Math.ceil(wx0 / step) * step; x <= wx1; x += step) { const [, sy] = toScreen(x, 0); ctx.moveTo(0, sy); ctx.lineTo(map.width, sy); }
  for (let y = Math.ceil(wy0 / step) * step; y <= wy1; y += step) { const [sx] = toScreen(0, y); ctx.moveTo(sx, 0); ctx.lineTo(sx, map.height); }
  ctx.stroke();
  if (geometry) {
    // Only what stands at the flown heights: not the floor, not the ceiling.
    let low = Infinity, high = -Infinity;
    const seen = (z) => { if (z < low) low = z; if (z > high) high = z; };
    for (const c of uavs.values()) {
      for (const m of c.info.missions) if (m.kind === "GotoXyz") seen(m.z);
      if (c.info.live && c.info.live.position) seen(c.info.live.position[2]);
    }
    if (low > high) { low = -3; high = -0.5; }
    ctx.fillStyle = "#8d99ae";
    for (const f of geometry) {
      if (!(f.z_min <= high && f.z_max >= low)) continue;
      ctx.beginPath();
      f.outline.forEach((p, i) => { const [sx, sy] = toScreen(p[0], p[1]); i ? ctx.lineTo(sx, sy) : ctx.moveTo(sx, sy); });
      ctx.closePath(); ctx.fill();
    }
  } else {
    ctx.fillStyle = "#555";
    for (const c of uavs.values()) for (const h of c.hits) { const [sx, sy] = toScreen(h[0], h[1]); ctx.fillRect(sx - 1, sy - 1, 2, 2); }
  }
  let k = 0;
  for (const c of uavs.values()) {
    const color = COLORS[k++ % COLORS.length], u = c.info, isSel = u.id === selected;
    if ($("overlay").checked) { ctx.globalAlpha = 0.35; for (const p of c.past) path(p, color, 1.5); ctx.globalAlpha = 1; }
    path(c.trail, color, isSel ? 2.5 : 1.5);
    // waypoints, the active one filled
    u.missions.forEach((m, i) => {
      if (m.kind !== "GotoXyz") return;
      const [sx, sy] = toScreen(m.x, m.y);
      ctx.strokeStyle = color; ctx.lineWidth = i === u.active ? 3 : 1.5;
      ctx.strokeRect(sx - 5, sy - 5, 10, 10);
      if (i === u.active) { ctx.fillStyle = color; ctx.fillRect(sx - 3, sy - 3, 6, 6); }
      ctx.fillStyle = "#222"; ctx.font = "11px sans-serif"; ctx.fillText(String(i + 1), sx + 7, sy - 6);
    });
    const l = u.live;
    if (!l || !l.position) continue;
    const [px, py] = toScreen(l.position[0], l.position[1]);
    const yaw = l.attitude ? l.attitude[2] : 0;
    if (isSel && l.laser) {
      ctx.strokeStyle = "rgba(230,57,70,0.25)"; ctx.lineWidth = 1; ctx.beginPath();
      const n = l.laser.ranges.length;
      for (let i = 0; i < n; i++) {
        const r = l.laser.ranges[i]; if (r === null) continue;
        const a = yaw + l.laser.fov / 2 - i * l.laser.resolution;
        const [ex, ey] = toScreen(l.position[0] + r * Math.cos(a), l.position[1] + r * Math.sin(a));
        ctx.moveTo(px, py); ctx.lineTo(ex, ey);
      }
      ctx.stroke();
    }
    if (isSel && l.sonars) {
      ctx.fillStyle = "rgba(42,157,143,0.15)";
      l.sonars.forEach((r, i) => {
        if (r === null) return;
        const a = yaw + i * Math.PI / 4, half = 0.26; // 8 sonars, 45° apart, ~30° cones
        ctx.beginPath(); ctx.moveTo(px, py);
        // screen angle: north up, east right -> angle a maps to atan2(-cos a, sin a)
        const sa = Math.atan2(-Math.cos(a), Math.sin(a));
        ctx.arc(px, py, r * view.scale, sa - half, sa + half); ctx.closePath(); ctx.fill();
      });
    }
    // the UAV: a triangle pointing along its heading
    ctx.save(); ctx.translate(px, py); ctx.rotate(yaw);
    ctx.fillStyle = color; ctx.strokeStyle = isSel ? "#000" : "#fff"; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.moveTo(0, -10); ctx.lineTo(6, 7); ctx.lineTo(-6, 7); ctx.closePath(); ctx.fill(); ctx.stroke();
    ctx.restore();
    ctx.fillStyle = "#222"; ctx.font = "11px sans-serif"; ctx.fillText(u.name, px + 9, py + 4);
  }
  // scale bar
  ctx.fillStyle = "#222"; ctx.fillRect(10, map.height - 14, step * view.scale, 3);
  ctx.fillText(step + " m", 14 + step * view.scale, map.height - 10);
}

function drawSide() {
  const c = selected !== null ? uavs.get(selected) : null;
  const av = $("altitude-view"), a = av.getContext("2d");
  a.fillStyle = "#fff"; a.fillRect(0, 0, av.width, av.height);
  a.fillStyle = "#222"; a.font = "11px sans-serif"; a.fillText("altitude view (x north → , altitude ↑)", 4, 12);
  const pl = $("plots"), p = pl.getContext("2d");
  p.fillStyle = "#fff"; p.fillRect(0, 0, pl.width, pl.height);
  if (!c) return;
  const pts = c.trail.concat(...($("overlay").checked ? c.past : []));
  if (pts.length) {
    const xs = pts.map((q) => q[0]), zs = pts.map((q) => -q[2]);
    const x0 = Math.min(...xs), x1 = Math.max(...xs) + 1e-6, z1 = Math.max(1, ...zs);
    const X = (x) => 10 + (x - x0) / (x1 - x0) * (av.width - 20), Z = (z) => av.height - 10 - z / z1 * (av.height - 30);
    for (const seg of [...($("overlay").checked ? c.past : []), c.trail]) {
      a.strokeStyle = seg === c.trail ? "#e63946" : "rgba(69,123,157,0.4)"; a.beginPath();
      seg.forEach((q, i) => (i ? a.lineTo(X(q[0]), Z(-q[2])) : a.moveTo(X(q[0]), Z(-q[2])))); a.stroke();
    }
  }
  const h = c.history; if (h.length < 2) return;
  const t0 = h[0][0], t1 = h[h.length - 1][0] + 1e-6;
  [["altitude m", 1, "#e63946"], ["speed m/s", 2, "#457b9d"], ["battery", 3, "#2a9d8f"]].forEach(([name, k, color], row) => {
    const top = row * 80, vals = h.map((r) => r[k]).filter((v) => v !== null);
    if (!vals.length) return;
    const lo = Math.min(0, ...vals), hi = Math.max(...vals, lo + 1e-6);
    p.strokeStyle = color; p.beginPath();
    h.forEach((r, i) => { if (r[k] === null) return; const x = 40 + (r[0] - t0) / (t1 - t0) * (pl.width - 50), y = top + 70 - (r[k] - lo) / (hi - lo) * 55; i ? p.lineTo(x, y) : p.moveTo(x, y); });
    p.stroke(); p.fillStyle = "#222"; p.fillText(`${name} (${fmt(vals[vals.length - 1])})`, 40, top + 12);
  });
}

function drawLog() {
  if (!logDirty) return;
  logDirty = false;
  const uf = $("log-uav").value, lf = $("log-level").value;
  const rank = { info: 0, warn: 1, error: 2 };
  const names = new Map([...uavs.values()].map((c) => [c.info.id, c.info.name]));
  const lines = logLines.filter((l) => (!uf || String(l.uav) === uf) && (!lf || rank[l.level] >= rank[lf])).slice(-2000);
  const box = $("log"), atEnd = box.scrollTop + box.clientHeight >= box.scrollHeight - 4;
  box.innerHTML = lines.map((l) => `<div class="${l.level}">${(names.get(l.uav) || "ucc").replace(/</g, "&lt;")} ${l.text.replace(/&/g, "&amp;").replace(/</g, "&lt;")}</div>`).join("");
  if (atEnd) box.scrollTop = box.scrollHeight;
}

function frame() {
  if (dirty) {
    const t = performance.now();
    drawMap(); drawSide();
    window.uccFrameTimes.push(performance.now() - t);
    if (window.uccFrameTimes.length > 10000) window.uccFrameTimes.shift();
    dirty = false;
  }
  drawLog();
  requestAnimationFrame(frame);
}

// ---- pan, zoom, click ----
let drag = null;
map.addEventListener("mousedown", (e) => { drag = { x: e.offsetX, y: e.offsetY, moved: false, cx: view.cx, cy: view.cy }; });
map.addEventListener("mousemove", (e) => {
  if (!drag) return;
  const dx = e.offsetX - drag.x, dy = e.offsetY - drag.y;
  if (Math.abs(dx) + Math.abs(dy) > 3) drag.moved = true;
  if (drag.moved) { view.cx = drag.cx + dy / view.scale; view.cy = drag.cy - dx / view.scale; dirty = true; }
});
map.addEventListener("mouseup", (e) => {
  const d = drag; drag = null;
  if (!d || d.moved) return;
  if (!needSelected()) return;
  const [x, y] = toWorld(e.offsetX * map.width / map.clientWidth, e.offsetY * map.height / map.clientHeight);
  send({ op: "add_mission", uav: selected, kind: "GotoXyz", x: x.toFixed(2), y: y.toFixed(2), z: $("mission-z").value });
});
map.addEventListener("wheel", (e) => {
  e.preventDefault();
  const f = e.deltaY < 0 ? 1.2 : 1 / 1.2;
  const [wx, wy] = toWorld(e.offsetX * map.width / map.clientWidth, e.offsetY * map.height / map.clientHeight);
  view.scale *= f; view.cx = wx + (view.cx - wx) / f; view.cy = wy + (view.cy - wy) / f; dirty = true;
}, { passive: false });

// ---- controls ----
$("connect").onclick = () => send({ op: "connect", host: $("server-host").value, port: $("server-port").value });
$("speed").onchange = () => send({ op: "speed", value: $("speed").value });
$("pause").onclick = () => send({ op: "pause", paused: $("pause").dataset.paused !== "true" });
$("create-uav").onclick = () => send({ op: "create", robot: $("robot-class").value, agent: $("agent-type").value, start: $("start-pose").value, name: $("uav-name").value });
$("uav-list").onclick = (e) => { const li = e.target.closest("li"); if (li) select(Number(li.dataset.id)); };
$("mission-add").onclick = () => { if (needSelected()) send({ op: "add_mission", uav: selected, kind: $("mission-type").value, x: $("mission-x").value, y: $("mission-y").value, z: $("mission-z").value, seconds: $("mission-seconds").value }); };
$("mission-list").onclick = (e) => { const i = e.target.dataset.remove; if (i !== undefined && needSelected()) send({ op: "remove_mission", uav: selected, index: Number(i) }); };
$("options").onclick = () => { if (needSelected()) send({ op: "options", uav: selected, prefix: $("prefix").value, pictures: $("pictures").value, autosave: $("autosave").checked }); };
$("loop-minus").onclick = () => { $("iterations").value = Math.max(1, (parseInt($("iterations").value, 10) || 1) - 1); };
$("loop-plus").onclick = () => { $("iterations").value = (parseInt($("iterations").value, 10) || 0) + 1; };
$("start").onclick = () => { if (needSelected()) send({ op: "start", uav: selected, iterations: $("iterations").value }); };
$("stop").onclick = () => { if (needSelected()) send({ op: "stop", uav: selected }); };
$("remove-uav").onclick = () => { if (needSelected()) send({ op: "remove", uav: selected }); };
$("fit").onclick = fit;
$("quit").onclick = () => { if (confirm("Stop every run and end the control center?")) send({ op: "quit" }); };
$("overlay").onchange = () => { dirty = true; };
$("log-uav").onchange = $("log-level").onchange = () => { logDirty = true; };
$("hide-log").onclick = () => { const l = $("log"); l.hidden = !l.hidden; $("hide-log").textContent = l.hidden ? "Show log" : "Hide log"; };
$("save-log").onclick = () => {
  const p = new URLSearchParams({ uav: $("log-uav").value, level: $("log-level").value });
  if (token) p.set("token", token);
  const a = document.createElement("a"); a.href = "/api/log?" + p; a.download = "ucc-gui.log"; a.click();
};
window.addEventListener("resize", () => { dirty = true; });
connect();
requestAnimationFrame(frame);
