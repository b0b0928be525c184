// The camera panel: the selected UAV's latest frame (/api/camera/ID, PNG), fetched only
// while the panel is open, one request at a time — the next one a period after the previous
// one loaded or failed — so a slow link or a hidden tab never piles requests up.

/** Milliseconds between the end of one frame's request and the next request. */
export const CAMERA_PERIOD_MS = 100;

/** The URL of UAV `uav`'s frame number `n` (`q`: the page's `?token=...` or ""). */
export function cameraUrl(uav, n, q = "") {
  return `/api/camera/${encodeURIComponent(uav)}${q ? q + "&" : "?"}n=${n}`;
}

/** Feeds `img` (anything with `src`, `onload`, `onerror`) with frames; `say(text)` shows why
 * there is none. `timer(fn, ms)` schedules (setTimeout in the page). */
export class CameraFeed {
  constructor(img, say, { q = "", period = CAMERA_PERIOD_MS, timer = (fn, ms) => setTimeout(fn, ms) } = {}) {
    Object.assign(this, { img, say, q, period, timer });
    this.uav = null; this.open = false; this.busy = false; this.waiting = false; this.n = 0;
    img.onload = () => { this.say(""); this.done(); };
    img.onerror = () => {
      this.say("no frame: the UAV needs a camera (AirRobot has one) and must be flying, on the local server");
      this.done();
    };
  }

  /** Shows UAV `uav` (null: none) while `open`. */
  show(uav, open) {
    this.uav = uav; this.open = open;
    if (!open || uav === null) this.say("");
    this.next();
  }

  /** Whether frames are wanted now. */
  get wanted() { return this.open && this.uav !== null; }

  next() {
    if (!this.wanted || this.busy || this.waiting) return;
    this.busy = true;
    this.img.src = cameraUrl(this.uav, ++this.n, this.q);
  }

  done() {
    this.busy = false;
    if (!this.wanted) return;
    this.waiting = true;
    this.timer(() => { this.waiting = false; this.next(); }, this.period);
  }
}
