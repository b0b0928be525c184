// Unit tests of the camera panel's feed: `node --test ucc-gui/tests/js/`.
import { test } from "node:test";
import assert from "node:assert/strict";
import { CameraFeed, cameraUrl } from "../../src/assets/camera.js";

/** An image element that records the URLs asked, and a timer run by hand. */
function fake() {
  const img = { asked: [], set src(u) { this.asked.push(u); } };
  const timers = [];
  const said = [];
  const feed = new CameraFeed(img, (t) => said.push(t), { q: "?token=a b", timer: (fn) => timers.push(fn) });
  return { img, timers, said, feed };
}

test("frame URLs carry the token", () => {
  assert.equal(cameraUrl(3, 7), "/api/camera/3?n=7");
  assert.equal(cameraUrl(3, 7, "?token=x"), "/api/camera/3?token=x&n=7");
});

test("nothing is fetched while the panel is closed or no UAV is selected", () => {
  const { img, feed } = fake();
  feed.show(1, false);
  feed.show(null, true);
  assert.deepEqual(img.asked, []);
});

test("one request at a time, the next a period after the previous one ended", () => {
  const { img, timers, feed } = fake();
  feed.show(1, true);
  feed.show(1, true); // selecting again while a frame loads asks nothing more
  assert.equal(img.asked.length, 1);
  img.onload();
  assert.equal(img.asked.length, 1, "waits for the period");
  assert.equal(timers.length, 1);
  timers.shift()();
  assert.deepEqual(img.asked, ["/api/camera/1?token=a b&n=1", "/api/camera/1?token=a b&n=2"]);
});

test("a failed frame says why and tries again; closing the panel stops the requests", () => {
  const { img, timers, said, feed } = fake();
  feed.show(2, true);
  img.onerror();
  assert.match(said.at(-1), /needs a camera/);
  timers.shift()();
  assert.equal(img.asked.length, 2);
  feed.show(2, false);
  img.onload();
  assert.equal(timers.length, 0, "closed: nothing scheduled");
  assert.equal(img.asked.length, 2);
});
