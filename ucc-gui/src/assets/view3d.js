// The 3D view (three.js, vendored: vendor/three.module.min.js). World frame x north, y east,
// z down becomes three's X = east, Y = up, Z = south. The map's solids are extruded with
// their heights; every UAV is one instance of one mesh (instanced: a thousand UAVs are one
// draw call) with its attitude; trails in 3D; the selected UAV's waypoints, laser beams
// and sonar cones; orbit (drag), pan (shift+drag or right drag), zoom (wheel), follow.
import * as THREE from "./vendor/three.module.min.js";
import { COLORS, WALL_COLOR, clamp, wheelFactor } from "./logic.js";
import { boxSize } from "./map2d.js";

const toThree = (x, y, z) => new THREE.Vector3(y, -z, -x);
/** Trail points drawn per UAV at most (all UAVs' trails are one line-segment geometry). */
const TRAIL_POINTS = 300;

export class View3d {
  constructor(box, store) {
    this.box = box; this.store = store; this.ok = false;
    try {
      this.renderer = new THREE.WebGLRenderer({ antialias: true });
    } catch (e) {
      const p = document.createElement("p"); p.className = "note";
      p.textContent = "The 3D view needs WebGL, which this browser does not offer: " + e.message;
      box.appendChild(p); return;
    }
    this.ok = true;
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    box.appendChild(this.renderer.domElement);
    const scene = this.scene = new THREE.Scene();
    scene.background = new THREE.Color("#eef1f5");
    this.camera = new THREE.PerspectiveCamera(50, 1, 0.05, 5000);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.4); sun.position.set(20, 40, 10); scene.add(sun);
    this.grid = new THREE.GridHelper(40, 40, 0x99a0b0, 0xd0d5df); scene.add(this.grid);
    this.orbit = { target: new THREE.Vector3(0, 1, 0), radius: 25, theta: 0.8, phi: 0.9 };
    this.solids = new THREE.Group(); scene.add(this.solids);
    const body = new THREE.ConeGeometry(0.22, 0.6, 4); body.rotateX(-Math.PI / 2); body.scale(1, 0.35, 1);
    this.body = body; this.capacity = 0; this.uavMesh = null;
    this.trails = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ vertexColors: true }));
    scene.add(this.trails);
    this.detail = new THREE.Group(); scene.add(this.detail);
    this.dirty = true; this.lastTrails = 0;
    this.controls();
  }

  setGeometry(geometry) {
    if (!this.ok) return;
    this.solids.clear();
    if (!geometry) return;
    const material = new THREE.MeshLambertMaterial({ color: WALL_COLOR, transparent: true, opacity: 0.55 });
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const f of geometry) {
      const h = f.z_max - f.z_min;
      if (!(h > 0) || f.outline.length < 3) continue;
      const shape = new THREE.Shape(f.outline.map((p) => new THREE.Vector2(p[1], p[0])));
      const g = new THREE.ExtrudeGeometry(shape, { depth: h, bevelEnabled: false });
      g.rotateX(-Math.PI / 2);
      const mesh = new THREE.Mesh(g, material);
      mesh.position.y = -f.z_max;
      this.solids.add(mesh);
      const edges = new THREE.LineSegments(new THREE.EdgesGeometry(g), new THREE.LineBasicMaterial({ color: 0x39414f }));
      edges.position.y = -f.z_max; this.solids.add(edges);
      for (const p of f.outline) { x0 = Math.min(x0, p[0]); x1 = Math.max(x1, p[0]); y0 = Math.min(y0, p[1]); y1 = Math.max(y1, p[1]); }
    }
    if (x0 <= x1) {
      this.orbit.target.copy(toThree((x0 + x1) / 2, (y0 + y1) / 2, -1));
      this.orbit.radius = clamp(Math.max(x1 - x0, y1 - y0) * 1.3, 5, 2000);
    }
    this.dirty = true;
  }

  controls() {
    const el = this.renderer.domElement; let drag = null;
    el.addEventListener("contextmenu", (e) => e.preventDefault());
    el.addEventListener("pointerdown", (e) => { drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 }; el.setPointerCapture(e.pointerId); });
    el.addEventListener("pointerup", () => { drag = null; });
    el.addEventListener("pointermove", (e) => {
      if (!drag) return;
      const dx = e.clientX - drag.x, dy = e.clientY - drag.y; drag.x = e.clientX; drag.y = e.clientY;
      const o = this.orbit;
      if (drag.pan) {
        const k = o.radius / Math.max(200, el.clientHeight);
        const right = new THREE.Vector3().setFromMatrixColumn(this.camera.matrix, 0);
        const up = new THREE.Vector3().setFromMatrixColumn(this.camera.matrix, 1);
        o.target.addScaledVector(right, -dx * k).addScaledVector(up, dy * k);
      } else {
        o.theta -= dx * 0.01; o.phi = clamp(o.phi - dy * 0.01, 0.05, Math.PI / 2 - 0.02);
      }
      this.dirty = true;
    });
    el.addEventListener("wheel", (e) => {
      e.preventDefault();
      this.orbit.radius = clamp(this.orbit.radius / wheelFactor(e.deltaY, e.deltaMode), 1, 3000); this.dirty = true;
    }, { passive: false });
  }

  ensureCapacity(n) {
    if (n <= this.capacity && this.uavMesh) return;
    this.capacity = Math.max(64, 1 << Math.ceil(Math.log2(n)));
    if (this.uavMesh) { this.scene.remove(this.uavMesh); this.uavMesh.dispose(); }
    this.uavMesh = new THREE.InstancedMesh(this.body, new THREE.MeshLambertMaterial({ color: 0xffffff }), this.capacity);
    this.uavMesh.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    this.scene.add(this.uavMesh);
  }

  draw(selected, follow, now) {
    if (!this.ok) return;
    const el = this.renderer.domElement, [w, h] = boxSize(this.box);
    if (w < 2 || h < 2) return;
    const size = this.renderer.getSize(new THREE.Vector2());
    if (size.x !== w || size.y !== h) { this.renderer.setSize(w, h, false); this.camera.aspect = w / h; this.camera.updateProjectionMatrix(); }
    el.style.width = ""; el.style.height = "";
    const uavs = this.store.uavs;
    this.ensureCapacity(uavs.size);
    const m = new THREE.Matrix4(), q = new THREE.Quaternion(), e = new THREE.Euler(0, 0, 0, "YXZ"), one = new THREE.Vector3(1, 1, 1), color = new THREE.Color();
    let i = 0, k = 0, sel = null;
    for (const c of uavs.values()) {
      const l = c.live, col = COLORS[k++ % COLORS.length];
      if (!l || !l.position) continue;
      const a = l.attitude || [0, 0, 0];
      e.set(a[1] || 0, -(a[2] || 0), -(a[0] || 0), "YXZ"); q.setFromEuler(e);
      const s = c.info.id === selected ? 1.6 : 1;
      m.compose(toThree(...l.position), q, one.set(s, s, s));
      this.uavMesh.setMatrixAt(i, m); this.uavMesh.setColorAt(i, color.set(col)); i++;
      if (c.info.id === selected) sel = c;
    }
    this.uavMesh.count = i;
    this.uavMesh.instanceMatrix.needsUpdate = true;
    if (this.uavMesh.instanceColor) this.uavMesh.instanceColor.needsUpdate = true;
    // Trails: rebuilt at most 4 times a second, decimated.
    if (now - this.lastTrails > 250) { this.lastTrails = now; this.buildTrails(selected); }
    this.buildDetail(sel);
    if (follow && sel && sel.live && sel.live.position) this.orbit.target.copy(toThree(...sel.live.position));
    const o = this.orbit;
    this.camera.position.set(o.target.x + o.radius * Math.cos(o.phi) * Math.sin(o.theta), o.target.y + o.radius * Math.sin(o.phi), o.target.z + o.radius * Math.cos(o.phi) * Math.cos(o.theta));
    this.camera.lookAt(o.target);
    this.renderer.render(this.scene, this.camera);
  }

  buildTrails(selected) {
    const pos = [], col = [], c3 = new THREE.Color();
    const budget = Math.max(20, Math.min(TRAIL_POINTS, Math.floor(200000 / Math.max(1, this.store.uavs.size))));
    let k = 0;
    const add = (pts, color, n) => {
      if (pts.length < 2) return;
      const step = Math.max(1, Math.ceil(pts.length / n));
      let prev = pts[0];
      for (let j = step; j < pts.length + step - 1; j += step) {
        const p = pts[Math.min(j, pts.length - 1)];
        pos.push(prev[1], -prev[2], -prev[0], p[1], -p[2], -p[0]);
        col.push(color.r, color.g, color.b, color.r, color.g, color.b);
        prev = p;
      }
    };
    for (const c of this.store.uavs.values()) {
      c3.set(COLORS[k++ % COLORS.length]);
      add(c.trail, c3, budget);
      if (c.info.id === selected) for (const p of c.past) add(p, c3.clone().lerp(new THREE.Color("#ffffff"), 0.5), 200);
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.Float32BufferAttribute(pos, 3));
    g.setAttribute("color", new THREE.Float32BufferAttribute(col, 3));
    this.trails.geometry.dispose(); this.trails.geometry = g;
  }

  buildDetail(c) {
    for (const o of this.detail.children) { o.geometry.dispose(); }
    this.detail.clear();
    if (!c) return;
    // Materials made once (they were made every frame and never disposed, as three.js asks).
    const mats = this.detailMaterials ??= {
      waypoints: new THREE.PointsMaterial({ color: 0x1a1a1a, size: 8, sizeAttenuation: false }),
      route: new THREE.LineDashedMaterial({ color: 0x555555 }),
      laser: new THREE.LineBasicMaterial({ color: 0xd62839, transparent: true, opacity: 0.35 }),
      sonar: new THREE.MeshBasicMaterial({ color: 0x1b7a6e, transparent: true, opacity: 0.18, depthWrite: false }),
    };
    const wp = c.info.missions.filter((m) => m.kind === "GotoXyz");
    if (wp.length) {
      const g = new THREE.BufferGeometry().setFromPoints(wp.map((m) => toThree(m.x, m.y, m.z)));
      this.detail.add(new THREE.Points(g, mats.waypoints));
      this.detail.add(new THREE.Line(g.clone(), mats.route));
    }
    const l = c.live;
    if (!l || !l.position) return;
    const p = toThree(...l.position), yaw = l.attitude ? l.attitude[2] : 0;
    if (l.laser) {
      const pts = [];
      l.laser.ranges.forEach((r, i) => {
        if (r === null) return;
        const a = yaw + l.laser.fov / 2 - i * l.laser.resolution;
        pts.push(p, toThree(l.position[0] + r * Math.cos(a), l.position[1] + r * Math.sin(a), l.position[2]));
      });
      this.detail.add(new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(pts), mats.laser));
    }
    if (l.sonars) {
      l.sonars.forEach((r, i) => {
        if (r === null || !(r > 0)) return;
        const a = yaw + i * Math.PI / 4, half = 0.26;
        const g = new THREE.ConeGeometry(Math.tan(half) * r, r, 16, 1, true);
        g.translate(0, -r / 2, 0); // apex at the origin, opening along -Y
        const cone = new THREE.Mesh(g, mats.sonar);
        cone.position.copy(p);
        const dir = toThree(Math.cos(a), Math.sin(a), 0).sub(toThree(0, 0, 0)).normalize();
        cone.quaternion.setFromUnitVectors(new THREE.Vector3(0, -1, 0), dir);
        this.detail.add(cone);
      });
    }
  }
}
