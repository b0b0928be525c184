// Unit tests of the page's logic: `node --test ucc-gui/tests/js/`.
import { test } from "node:test";
import assert from "node:assert/strict";
import {
  bounds, range, fitView, wheelFactor, zoomAt, niceStep, ticks, appendDecimated, appendCapped,
  contrast, splitGeometry, centroid, VICTIM_COLOR, Store, SCALE_MAX, SCALE_MIN, WALL_COLOR, WARN_COLOR, ERROR_COLOR, MAX_TRAIL, MAX_PAST,
} from "../../src/assets/logic.js";

test("bounds of 300,000 points do not overflow the stack (issue #23, defect 2)", () => {
  const pts = Array.from({ length: 300000 }, (_, i) => [i % 1000, (i % 777) - 776]);
  const b = bounds((visit) => { for (const p of pts) visit(p[0], p[1]); });
  assert.deepEqual(b, { x0: 0, x1: 999, y0: -776, y1: 0 });
  assert.equal(bounds(() => {}), null);
  assert.deepEqual(range([3, null, -1, NaN, 7]), [-1, 7]);
});

test("fit and zoom stay within the limits at any coordinate (defect 5)", () => {
  const far = fitView({ x0: 0, x1: 1e12, y0: 0, y1: 0 }, 800, 600);
  assert.ok(far.scale >= SCALE_MIN);
  const near = fitView({ x0: 0, x1: 0, y0: 0, y1: 0 }, 800, 600);
  assert.ok(near.scale <= SCALE_MAX);
  let view = { cx: 0, cy: 0, scale: 20 };
  for (let i = 0; i < 1000; i++) view = zoomAt(view, wheelFactor(-100), 1, 1);
  assert.equal(view.scale, SCALE_MAX);
  for (let i = 0; i < 1000; i++) view = zoomAt(view, wheelFactor(100), 1, 1);
  assert.equal(view.scale, SCALE_MIN);
});

test("the wheel zooms by distance, not by event count", () => {
  assert.ok(wheelFactor(-1) > 1 && wheelFactor(-1) < wheelFactor(-100));
  assert.ok(Math.abs(wheelFactor(-3, 1) - wheelFactor(-48)) < 1e-12, "lines are 16 px");
  assert.equal(wheelFactor(-1e9), 2);
  assert.equal(wheelFactor(1e9), 0.5);
});

test("grid steps give a bounded number of lines at any zoom", () => {
  for (const scale of [SCALE_MIN, 0.01, 1, 17, 300, SCALE_MAX]) {
    const step = niceStep(scale, 40);
    assert.ok(step * scale >= 40 && step * scale < 40 * 5.01, `${scale}: ${step}`);
  }
  assert.deepEqual(ticks(0, 10, 5), [0, 2, 4, 6, 8, 10]);
  assert.ok(ticks(-1e12, 1e12).length <= 100);
});

test("trails are decimated, lists capped", () => {
  const t = [];
  for (let i = 0; i < 100000; i++) appendDecimated(t, [[i, 0, 0]], MAX_TRAIL);
  assert.ok(t.length <= MAX_TRAIL);
  assert.equal(t[t.length - 1][0], 99999, "the newest point is kept");
  assert.equal(t[0][0], 0, "the first point is kept");
  const l = [];
  appendCapped(l, [1, 2, 3, 4, 5], 3);
  assert.deepEqual(l, [3, 4, 5]);
});

test("text and walls contrast at least 4.5:1 on white (defect 9)", () => {
  for (const c of [WALL_COLOR, WARN_COLOR, ERROR_COLOR]) assert.ok(contrast(c, "#ffffff") >= 4.5, c);
  assert.ok(Math.abs(contrast("#000000", "#ffffff") - 21) < 1e-9);
});

test("the store merges only what changed and stays bounded over a long loop", () => {
  const s = new Store();
  s.merge({ server: { addr: "a" }, uavs: [{ id: 1, info: { name: "U", status: "running" }, trail: [[0, 0, 0]] }], log: [] });
  assert.equal(s.uavs.get(1).info.name, "U");
  const ch = s.merge({ server: { addr: "a" }, uavs: [{ id: 1, trail: [[1, 0, 0]] }], log: [] });
  assert.equal(ch.info, false);
  assert.equal(s.uavs.get(1).info.name, "U", "info kept when not sent");
  assert.equal(s.uavs.get(1).trail.length, 2);
  for (let i = 0; i < 10000; i++) {
    const past = [Array.from({ length: 300 }, (_, k) => [k, i, 0])];
    s.merge({ uavs: [{ id: 1, trail_reset: true, past, trail: [[0, 0, 0]] }], log: [{ seq: i, text: "x" }] });
  }
  assert.ok(s.uavs.get(1).past.length <= MAX_PAST);
  assert.ok(s.log.length <= 2000, `${s.log.length} log lines kept`);
  assert.equal(s.log[s.log.length - 1].seq, 9999, "the newest line is kept");
  s.merge({ removed: [1], uavs: [] });
  assert.equal(s.uavs.size, 0);
});

test("victims are split from the solids and named at their centre (issue 20)", () => {
  const wall = { outline: [[0, 0], [1, 0], [1, 1], [0, 1]], z_min: -3, z_max: 0 };
  const victim = { outline: [[2, 2], [4, 2], [4, 3], [2, 3]], z_min: -0.3, z_max: 0, victim: "Victim1", class: "FemaleVictim" };
  const { solids, victims } = splitGeometry([wall, victim]);
  assert.deepEqual(solids, [wall]);
  assert.deepEqual(victims.map((v) => v.victim), ["Victim1"]);
  assert.deepEqual(centroid(victim.outline), [3, 2.5]);
  assert.deepEqual(splitGeometry(null), { solids: [], victims: [] });
  assert.notEqual(VICTIM_COLOR, WALL_COLOR);
});
