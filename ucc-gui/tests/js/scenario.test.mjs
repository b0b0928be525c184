// Unit tests of the scenario page's logic (issue #22): `node --test ucc-gui/tests/js/`.
import { test } from "node:test";
import assert from "node:assert/strict";
import {
  ScenarioState, decodeGrid, applyGridChanges, levelColor, linkSegments, formatMetric, LEVELS,
} from "../../src/assets/scenario.js";

test("the grid comes whole as digits, then as changes; bad cells are ignored", () => {
  const levels = decodeGrid("0190x");
  assert.deepEqual([...levels], [0, 1, 9, 0, 0]);
  const changed = applyGridChanges(levels, [0, 3, 4, 9, 99, 1, -1, 2, 2, 12, 1]);
  assert.deepEqual(changed, [0, 4], "out of range indices and levels are skipped; an odd tail too");
  assert.deepEqual([...levels], [3, 1, 9, 0, 9]);
});

test("heat colours: never seen is pale red, then greener the longer", () => {
  const [r0, g0] = levelColor(0);
  assert.ok(r0 > g0, "unseen is reddish");
  let last = levelColor(1);
  assert.ok(last[1] > last[0], "seen is greenish");
  for (let l = 2; l <= LEVELS; l++) {
    const c = levelColor(l);
    assert.ok(c[0] < last[0] && c[1] < last[1], `level ${l} darker than ${l - 1}`);
    last = c;
  }
  assert.deepEqual(levelColor(LEVELS + 5), levelColor(LEVELS));
});

test("the link strip's segments follow the changes up to now", () => {
  assert.deepEqual(linkSegments([], 10), []);
  assert.deepEqual(linkSegments([[0.1, false], [32, true], [40, false]], 50), [
    { from: 0.1, to: 32, up: false }, { from: 32, to: 40, up: true }, { from: 40, to: 50, up: false },
  ]);
  assert.deepEqual(linkSegments([[5, true]], 3), [{ from: 5, to: 5, up: true }], "never backwards");
});

test("figures show with their units; unmeasured ones as a dash", () => {
  assert.equal(formatMetric("coverage_pct", 87.345), "87.3 %");
  assert.equal(formatMetric("first_find_s", 4.8), "4.8 s");
  assert.equal(formatMetric("drop_error_m", 0.1234), "0.12 m");
  assert.equal(formatMetric("victims_found", 6), "6");
  assert.equal(formatMetric("battery_used", 0.04), "0.04");
  assert.equal(formatMetric("all_found_s", null), "–");
  assert.equal(formatMetric("link_pct", NaN), "–");
});

test("the state merges the hub's updates: fixed, grid, victims, link, rows; a new iteration starts over", () => {
  const s = new ScenarioState();
  const fixed = { name: "search", time_limit: 150, grid: { origin: [0, 0], cell: 1, shape: [2, 3], area: [[0, 0], [2, 3]] }, pads: [{ name: "base", pad: { at: [-5, 0], radius: 1 } }] };
  let c = s.merge({ fixed, reset: true, grid_full: "000000", status: "running", metrics: [["coverage_pct", 0]], iteration: 1 });
  assert.ok(c.fixed && c.grid);
  assert.equal(s.levels.length, 6);
  assert.equal(s.changedCells, null, "the first paint is whole");
  s.changedCells = []; // painted
  c = s.merge({ grid: [1, 1, 5, 2], victims: [{ name: "V", at: [1, 1], found: 3.5 }], link: [[0.1, true]], metrics: [["coverage_pct", 33.3]] });
  assert.ok(c.grid && c.victims && !c.fixed);
  assert.deepEqual(s.changedCells, [1, 5], "only the changed cells are painted again");
  assert.equal(s.metric("coverage_pct"), 33.3);
  assert.equal(s.metric("nothing"), null);
  s.merge({ link: [[9, false]], rows: [{ iteration: 1, seed: "1", ending: "done", values: [1] }] });
  assert.deepEqual(s.link, [[0.1, true], [9, false]]);
  assert.equal(s.rows.length, 1);
  // The next iteration: grid, victims and link start over; the rows stay.
  s.merge({ reset: true, grid_full: "000000", iteration: 2 });
  assert.deepEqual([...s.levels], [0, 0, 0, 0, 0, 0]);
  assert.deepEqual(s.link, []);
  assert.deepEqual(s.victims, []);
  assert.equal(s.rows.length, 1);
  assert.equal(s.iteration, 2);
  const pts = s.points();
  assert.ok(pts.some((p) => p[0] === -5), "the base pad is in the fit");
  // A new scenario: everything goes.
  s.merge({ fixed: { ...fixed, name: "other" } });
  assert.equal(s.rows.length, 0);
});
