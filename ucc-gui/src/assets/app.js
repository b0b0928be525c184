// The UAV Control Center page: renders what the Rust side sends, sends what the user asks.
// The Rust side owns the state and checks every request; this page keeps only what it draws
// (logic.js: the store, bounds, zoom; map2d.js, side.js, plots.js, view3d.js: the views).
// Text from the server (names, log lines, file names) is only ever inserted as text.
import { Store, WALL_COLOR, MAX_LOG } from "./logic.js";
import { Map2d } from "./map2d.js";
import { SideView } from "./side.js";
import { Plots } from "./plots.js";
import { View3d } from "./view3d.js";
import { CameraFeed } from "./camera.js";
import { ScenarioPanel } from "./scenario.js";

const $ = (id) => document.getElementById(id);
const token = new URLSearchParams(location.search).get("token");
const q = token ? "?token=" + encodeURIComponent(token) : "";
const store = new Store();
let selected = null, ws = null, logDirty = false, dirty = true, optionsShown = null;
const map = new Map2d($("map"), store);
const sides = { north: new SideView($("side-north"), 0), east: new SideView($("side-east"), 1) };
let plots = null, view3d = null, last3d = -1e9, pending3d = false;
const camera = new CameraFeed($("camera"), (t) => { $("camera-status").textContent = t; }, { q });
let serverGeometry = null;
const scenario = new ScenarioPanel({
  $, el, send, q,
  onGeometry: (g) => { map.geometry = g || serverGeometry; map.fitted = false; if (view3d) view3d.setGeometry(map.geometry); dirty = true; },
});
map.layer = scenario.layer;
const showCamera = () => camera.show(selected, $("camera-panel").open);
$("camera-panel").addEventListener("toggle", showCamera);
window.uccFrameTimes = []; // draw time of each frame, ms (the benchmark reads it)
window.uccUpdates = 0; // state updates received
window.uccBytes = 0; // characters received over the WebSocket (the benchmark reads it)
window.uccParts = { map: 0, side: 0, plots: 0, view3d: 0, update: 0 }; // ms spent per part (the benchmark reads it)

/** An element with text (never HTML). */
function el(tag, text, attrs = {}) {
  const e = document.createElement(tag);
  if (text !== undefined && text !== null) e.textContent = text;
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  return e;
}

function send(obj) { if (ws && ws.readyState === 1) ws.send(JSON.stringify(obj)); }
function showError(message) {
  const e = $("error"); e.textContent = message; e.hidden = false;
  clearTimeout(showError.t); showError.t = setTimeout(() => { e.hidden = true; }, 8000);
}
function needSelected() { if (selected === null) { showError("create or select a UAV first"); return false; } return true; }

function connect() {
  ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws" + q);
  ws.onopen = () => { $("conn").textContent = "live"; viewKey = null; };
  ws.onclose = () => { $("conn").textContent = "disconnected — reload the page"; };
  ws.onmessage = (ev) => { window.uccBytes += ev.data.length; receive(JSON.parse(ev.data)); };
}

function receive(m) {
  if (m.type === "hello") hello(m);
  else if (m.type === "state") update(m);
  else if (m.type === "error") showError(m.message);
  else if (m.type === "created") select(m.uav);
}

function showAddr(addr) {
  const i = addr.lastIndexOf(":");
  if (i < 0) return;
  if (document.activeElement !== $("server-host")) $("server-host").value = addr.slice(0, i);
  if (document.activeElement !== $("server-port")) $("server-port").value = addr.slice(i + 1);
}

function hello(m) {
  serverGeometry = m.geometry;
  map.geometry = scenario.geometry() || m.geometry;
  scenario.hello(m.scenarios || []);
  $("agent-type").replaceChildren(...m.agents.map((a) => el("option", a)));
  $("robots").replaceChildren(...m.robots.map((r) => el("option", null, { value: r })));
  $("time-scale-row").hidden = !m.local;
  if (m.addr) showAddr(m.addr);
  if (view3d) view3d.setGeometry(m.geometry);
  map.fitted = false; dirty = true;
}

function update(m) {
  window.uccUpdates++;
  const t0 = performance.now();
  try { merge(m); } finally { window.uccParts.update += performance.now() - t0; }
}

function merge(m) {
  const before = store.server;
  const changed = store.merge(m);
  const s = store.server;
  if (changed.server) {
    $("server-info").textContent = `${s.local ? "local server" : "server"} ${s.addr}${s.map ? " · map " + s.map : ""}`;
    if (!before || before.addr !== s.addr) showAddr(s.addr);
    if (document.activeElement !== $("time-scale")) $("time-scale").value = s.time_scale;
    $("time-scale-row").hidden = !s.local;
    if (!s.local) serverGeometry = null;
    if (!s.local && map.geometry && !scenario.geometry()) { map.geometry = null; map.fitted = false; if (view3d) view3d.setGeometry(null); }
    $("pause").textContent = s.paused ? "Resume" : "Pause";
    $("pause").dataset.paused = s.paused;
  }
  if (selected !== null && !store.uavs.has(selected)) { selected = null; showCamera(); }
  if (selected === null && store.uavs.size) select(store.uavs.keys().next().value);
  if (changed.log) logDirty = true;
  if (m.scenario) scenario.update(m.scenario);
  panels(changed);
  dirty = true;
}

function select(id) {
  selected = id; send({ op: "select", uav: id }); showCamera();
  optionsShown = null; listKey = null;
  panels({ info: true, files: true }); dirty = true;
  const li = $("uav-list").querySelector(`li[data-id="${id}"]`);
  if (li && document.activeElement && document.activeElement.closest && document.activeElement.closest("#uav-list")) li.focus();
}

const fmt = (v, d = 2) => (v === null || v === undefined ? "–" : v.toFixed(d));
const fmt3 = (a, d = 2) => (a ? a.map((v) => fmt(v, d)).join(",") : "–");
let listKey = null, missionKey = null, filesKey = null, logUavKey = null;

function panels(changed) {
  const all = [...store.uavs.values()];
  const key = JSON.stringify([selected, all.map((c) => [c.info.id, c.info.name, c.info.status, c.info.iteration, c.info.iterations])]);
  if (key !== listKey) {
    listKey = key;
    $("uav-list").replaceChildren(...all.map((c) => {
      const u = c.info;
      const li = el("li", `${u.name} · ${u.robot} · ${u.agent} · ${u.status}${u.status === "running" ? " " + u.iteration + "/" + u.iterations : ""}`,
        { "data-id": u.id, tabindex: "0", role: "option", "aria-selected": String(u.id === selected) });
      return li;
    }));
    const lk = JSON.stringify(all.map((c) => [c.info.id, c.info.name]));
    if (lk !== logUavKey) {
      logUavKey = lk;
      const lu = $("log-uav"), v = lu.value;
      lu.replaceChildren(el("option", "all UAVs", { value: "" }), ...all.map((c) => el("option", c.info.name, { value: c.info.id })));
      lu.value = v;
    }
  }
  const c = selected !== null ? store.uavs.get(selected) : null;
  if (!c) { $("title").textContent = "UAV Control Center"; return; }
  const u = c.info, l = c.live;
  if (optionsShown !== u.id && u.prefix !== undefined) {
    optionsShown = u.id;
    $("prefix").value = u.prefix; $("pictures").value = u.pictures; $("autosave").checked = u.autosave;
  }
  $("title").textContent = `UAV Control Center — ${u.name}: ${u.robot}, agent ${u.agent}`;
  $("mission-owner").textContent = "of " + u.name;
  const mk = JSON.stringify([u.id, u.active, u.missions.map((m) => m.text)]);
  if (mk !== missionKey) {
    missionKey = mk;
    $("mission-list").replaceChildren(...u.missions.map((m, i) => {
      const li = el("li", `${i === u.active ? "▶ " : ""}${m.text} `, i === u.active ? { class: "active" } : {});
      li.appendChild(el("button", "×", { type: "button", "data-remove": i, "aria-label": `remove mission ${i + 1}` }));
      return li;
    }));
  }
  $("iteration-counter").textContent = String(u.iteration);
  $("iteration-total").textContent = String(u.iterations);
  $("run-status").textContent = u.status + (u.error ? ": " + u.error : "");
  $("run-status").dataset.status = u.status;
  $("uav-position").textContent = l && l.position ? fmt3(l.position) : "";
  $("uav-velocity").textContent = l ? fmt3(l.velocity) + " m/s" : "";
  $("uav-attitude").textContent = l ? fmt3(l.attitude, 3) + " rad" : "";
  $("uav-battery").textContent = l && l.battery ? `${(l.battery.level * 100).toFixed(0)}% (${l.battery.remaining} s)` : "";
  $("uav-time").textContent = l ? fmt(l.time) + " s" : "";
  // Faults the server applied (usar-server --faults): how many, and the latest.
  $("uav-faults").textContent = l && l.faults ? `${l.faults.count}: ${l.faults.last} (t=${fmt(l.faults.time)} s)` : "";
  let sensors = "";
  if (l) {
    if (l.sonars) sensors += "sonars " + l.sonars.map((s) => fmt(s)).join(" ") + "\n";
    if (l.altitude !== undefined) sensors += `altitude ${fmt(l.altitude)} · free above ${fmt(l.free_above)} · below ${fmt(l.free_below)}\n`;
    if (l.laser) {
      let min = Infinity; for (const r of l.laser.ranges) if (r !== null && r < min) min = r;
      sensors += `laser ${l.laser.ranges.length} beams, min ${fmt(Number.isFinite(min) ? min : null)} m\n`;
    }
    if (l.command) sensors += "command fwd,right,up,yaw " + l.command.map((v) => fmt(v, 1)).join(",") + "\n";
  }
  $("sensors").textContent = sensors;
  // The download links change only when the files do (a held click reaches them).
  const fk = `${u.id}:${c.filesVersion}`;
  if (fk !== filesKey) {
    filesKey = fk;
    const f = c.files || { total: 0, recent: [] };
    const links = (f.recent || []).map((x) => el("a", x.name, { href: `/api/files/${u.id}/${x.index}${q}`, download: x.name }));
    const more = f.total > links.length ? [el("small", `${f.total} files in all; the older ones are in the log directory`)] : [];
    $("files").replaceChildren(...links, ...more);
  }
}

function drawLog() {
  if (!logDirty) return;
  logDirty = false;
  const uf = $("log-uav").value, lf = $("log-level").value;
  const rank = { info: 0, warn: 1, error: 2 };
  const names = new Map([...store.uavs.values()].map((c) => [c.info.id, c.info.name]));
  const lines = [];
  for (let i = store.log.length - 1; i >= 0 && lines.length < MAX_LOG; i--) {
    const l = store.log[i];
    if ((!uf || String(l.uav) === uf) && (!lf || rank[l.level] >= rank[lf])) lines.push(l);
  }
  lines.reverse();
  const box = $("log"), atEnd = box.scrollTop + box.clientHeight >= box.scrollHeight - 4;
  box.replaceChildren(...lines.map((l) => el("div", `${names.get(l.uav) || "ucc"} ${l.text}`, { class: l.level })));
  if (atEnd) box.scrollTop = box.scrollHeight;
}

function drawMap() { map.draw(selected, $("overlay").checked); }

// The hub sends full detail only for the UAVs in the map's view (and the selected one): tell
// it the view when it changes, at most every 150 ms (a drag sends a few, not hundreds).
let viewKey = null, viewSent = -1e9;
function syncView(now) {
  // A map not laid out (no size) shows nothing: say nothing rather than an empty view.
  if (!map.fitted || map.w < 10 || map.h < 10 || !ws || ws.readyState !== 1 || now - viewSent < 150) return;
  const r = map.viewRect(), key = r.map((v) => v.toPrecision(5)).join();
  if (key === viewKey) return;
  viewKey = key; viewSent = now;
  send({ op: "view", x0: r[0], x1: r[1], y0: r[2], y1: r[3] });
}

function frame(now) {
  try {
    if (dirty || pending3d || (view3d && view3d.dirty)) {
      pending3d = false;
      const t = performance.now(), parts = window.uccParts;
      drawMap();
      const t1 = performance.now();
      const c = selected !== null ? store.uavs.get(selected) : null;
      sides.north.draw(c, map.geometry, $("overlay").checked);
      sides.east.draw(c, map.geometry, $("overlay").checked);
      const t2 = performance.now();
      if (plots) plots.draw(c);
      const t3 = performance.now();
      parts.map += t1 - t; parts.side += t2 - t1; parts.plots += t3 - t2;
      // The 3D view at most 15 times a second (software WebGL is slow); the rest, every frame.
      if (view3d && now - last3d > 66) { view3d.draw(selected, $("follow").checked, now); view3d.dirty = false; last3d = now; parts.view3d += performance.now() - t3; }
      else if (view3d) pending3d = true;
      window.uccFrameTimes.push(performance.now() - t);
      if (window.uccFrameTimes.length > 10000) window.uccFrameTimes.splice(0, 5000);
      dirty = false;
    }
    drawLog();
    syncView(now);
  } catch (e) {
    console.error(e); showError("drawing failed: " + e.message);
  }
  requestAnimationFrame(frame);
}

// ---- pan, zoom, click on the map (CSS pixels) ----
let drag = null;
const mapEl = $("map");
mapEl.addEventListener("mousedown", (e) => { drag = { x: e.offsetX, y: e.offsetY, moved: false, cx: map.view.cx, cy: map.view.cy }; });
mapEl.addEventListener("mousemove", (e) => {
  if (!drag) return;
  const dx = e.offsetX - drag.x, dy = e.offsetY - drag.y;
  if (Math.abs(dx) + Math.abs(dy) > 3) drag.moved = true;
  if (drag.moved) { map.view.cx = drag.cx + dy / map.view.scale; map.view.cy = drag.cy - dx / map.view.scale; dirty = true; }
});
mapEl.addEventListener("mouseup", (e) => {
  const d = drag; drag = null;
  if (!d || d.moved) return;
  if (!needSelected()) return;
  const [x, y] = map.toWorld(e.offsetX, e.offsetY);
  send({ op: "add_mission", uav: selected, kind: "GotoXyz", x: x.toFixed(2), y: y.toFixed(2), z: $("mission-z").value });
});
mapEl.addEventListener("wheel", (e) => {
  e.preventDefault();
  const r = mapEl.getBoundingClientRect();
  map.wheel(e.deltaY, e.deltaMode, e.clientX - r.left, e.clientY - r.top); dirty = true;
}, { passive: false });

// ---- controls: every form submits with Enter ----
const onSubmit = (id, f) => { $(id).addEventListener("submit", (e) => { e.preventDefault(); f(e.submitter); }); };
onSubmit("server-form", () => send({ op: "connect", host: $("server-host").value, port: $("server-port").value }));
$("time-scale").onchange = () => send({ op: "time_scale", value: $("time-scale").value });
$("pause").onclick = () => send({ op: "pause", paused: $("pause").dataset.paused !== "true" });
onSubmit("create-form", () => send({ op: "create", robot: $("robot-class").value, agent: $("agent-type").value, start: $("start-pose").value, name: $("uav-name").value }));
$("uav-list").addEventListener("click", (e) => { const li = e.target.closest("li"); if (li) select(Number(li.dataset.id)); });
$("uav-list").addEventListener("keydown", (e) => {
  const li = e.target.closest("li"); if (!li) return;
  if (e.key === "Enter" || e.key === " ") { e.preventDefault(); e.stopPropagation(); select(Number(li.dataset.id)); }
  else if (e.key === "ArrowDown" && li.nextElementSibling) { e.preventDefault(); li.nextElementSibling.focus(); }
  else if (e.key === "ArrowUp" && li.previousElementSibling) { e.preventDefault(); li.previousElementSibling.focus(); }
});
onSubmit("mission-form", () => { if (needSelected()) send({ op: "add_mission", uav: selected, kind: $("mission-type").value, x: $("mission-x").value, y: $("mission-y").value, z: $("mission-z").value, seconds: $("mission-seconds").value }); });
$("mission-list").addEventListener("click", (e) => { const i = e.target.dataset.remove; if (i !== undefined && needSelected()) send({ op: "remove_mission", uav: selected, index: Number(i) }); });
onSubmit("options-form", () => { if (needSelected()) send({ op: "options", uav: selected, prefix: $("prefix").value, pictures: $("pictures").value, autosave: $("autosave").checked }); });
$("loop-minus").onclick = () => { $("iterations").value = Math.max(1, (parseInt($("iterations").value, 10) || 1) - 1); };
$("loop-plus").onclick = () => { $("iterations").value = (parseInt($("iterations").value, 10) || 0) + 1; };
onSubmit("run-form", () => { if (needSelected()) send({ op: "start", uav: selected, iterations: $("iterations").value }); });
$("stop").onclick = () => { if (needSelected()) send({ op: "stop", uav: selected }); };
$("remove-uav").onclick = () => { if (needSelected()) send({ op: "remove", uav: selected }); };
$("fit").onclick = () => { map.fit(); dirty = true; };
$("quit").onclick = () => { if (confirm("Stop every run and end the control center?")) send({ op: "quit" }); };
$("overlay").onchange = $("follow").onchange = () => { dirty = true; };
$("log-uav").onchange = $("log-level").onchange = () => { logDirty = true; };
$("hide-log").onclick = () => { const l = $("log"); l.hidden = !l.hidden; $("hide-log").textContent = l.hidden ? "Show log" : "Hide log"; };
$("save-log").onclick = () => {
  const p = new URLSearchParams({ uav: $("log-uav").value, level: $("log-level").value });
  if (token) p.set("token", token);
  const a = document.createElement("a"); a.href = "/api/log?" + p; a.download = "ucc-gui.log"; a.click();
};
window.addEventListener("resize", () => { dirty = true; });
window.addEventListener("ucc-resize", () => { dirty = true; if (view3d) view3d.dirty = true; });

// For tests and the benchmark: the page's objects.
window.ucc = {
  get view() { return map.view; }, uavs: store.uavs, store, send, receive, select,
  fit: () => { map.fit(); dirty = true; }, toScreen: (x, y) => map.toScreen(x, y), drawMap,
  side: sides, WALL_COLOR, MAX_LOG, get view3d() { return view3d; }, get plots() { return plots; }, camera, scenario,
};

function start() {
  try { plots = new Plots($("plots")); } catch (e) { console.error(e); }
  try { view3d = new View3d($("view3d"), store); if (view3d.ok) view3d.setGeometry(map.geometry); } catch (e) { console.error(e); }
  connect();
  requestAnimationFrame(frame);
}
// uPlot is a classic deferred script: it has run once the document is parsed.
if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start); else start();
