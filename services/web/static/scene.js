// The 3D scene in the robot base frame (metres, +z up; the user stands at +x facing -x):
// workspace grid, table area, objects, the arm (its links posed by robot/state's joints:
// `pandaLinkPoints`), TCP and gripper, hand skeletons (already in the base
// frame: the server applies each frame's to_base), gaze point, episode focus, pointing ray,
// and the intent's target highlighted. Labels are HTML over the canvas, laid out after each
// render so that no two overlap (`layOutLabels`).
import * as THREE from "three";
import { OrbitControls } from "three/addons/OrbitControls.js";

const HAND_COLOURS = { left: 0x39c5cf, right: 0xf778ba };
const OBJECT_COLOURS = { cup: 0x58a6ff, box: 0xd29922, drawer: 0x8b949e };
const TARGET = 0xffe066;
// The Panda / FR3 kinematics: Craig's modified DH parameters (a, d, alpha) of joints 1..7, m
// and rad (Franka's documentation), then the flange 0.107 m and the Franka Hand's TCP 0.1034 m
// further along joint 7's axis. cbgo.foxglove.arm holds the same table for Foxglove.
const PANDA_DH = [[0, 0.333, 0], [0, 0, -Math.PI / 2], [0, 0.316, Math.PI / 2],
  [0.0825, 0, Math.PI / 2], [-0.0825, 0.384, -Math.PI / 2], [0, 0, Math.PI / 2],
  [0.088, 0, Math.PI / 2]];
const FLANGE_D = 0.107, HAND_TCP_D = 0.1034;
const LINK_RADIUS = 0.03, JOINT_RADIUS = 0.04;  // m: simple geometry, no meshes

export class SceneView {
  // canvas: the WebGL canvas; labelLayer: an element stacked over it, of the same size.
  constructor(canvas, labelLayer) {
    this.canvas = canvas;
    this.labelLayer = labelLayer;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x0d1014);
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.01, 20);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(1.45, 0.62, 0.62);  // over the user's right shoulder
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.target.set(0.6, 0, 0.1);
    this.controls.update();
    this.changed = true;  // render only when something moved: an idle page costs no GPU
    this.controls.addEventListener("change", () => { this.changed = true; });
    this.scene.add(new THREE.AmbientLight(0xffffff, 0.55));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(1, 0.5, 2);
    this.scene.add(sun);
    this.static = new THREE.Group(); this.objects = new THREE.Group();
    this.dynamic = new THREE.Group();
    this.scene.add(this.static, this.objects, this.dynamic);
    this.addRobotBase();
    this.objectsKey = "";
  }

  addRobotBase() {
    const base = new THREE.Mesh(new THREE.CylinderGeometry(0.07, 0.09, 0.06, 32),
      new THREE.MeshStandardMaterial({ color: 0xdddddd }));
    base.rotation.x = Math.PI / 2; base.position.set(0, 0, 0.03);
    this.scene.add(base, label("robot base", [0, 0, 0.1], "#c9d1d9"));
    this.scene.add(new THREE.AxesHelper(0.12));
  }

  // The documented workspace (cbgo/sim/info, else cbgo.world.workspace's default grid).
  setWorkspace(ws) {
    release(this.static);
    this.changed = true;
    this.opensAwayBelowX = ws.drawer_opens_away_below_x ?? null;
    const area = ws.table_area;
    const pad = 0.08;
    const table = new THREE.Mesh(
      new THREE.PlaneGeometry(area.x[1] - area.x[0] + 2 * pad, area.y[1] - area.y[0] + 2 * pad),
      new THREE.MeshStandardMaterial({ color: 0x2a2f36, side: THREE.DoubleSide }));
    table.position.set((area.x[0] + area.x[1]) / 2, (area.y[0] + area.y[1]) / 2, -0.001);
    this.static.add(table);
    this.static.add(rectangle(area.x, area.y, 0, 0x58a6ff));
    const dots = [];
    for (const x of ws.columns_x) for (const y of ws.columns_y) for (const z of ws.levels_z) dots.push(x, y, z);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.Float32BufferAttribute(dots, 3));
    this.static.add(new THREE.Points(geometry, new THREE.PointsMaterial({ color: 0x6e7681, size: 0.008 })));
    const lines = [];
    for (const x of ws.columns_x) lines.push([x, ws.columns_y[0], 0], [x, ws.columns_y.at(-1), 0]);
    for (const y of ws.columns_y) lines.push([ws.columns_x[0], y, 0], [ws.columns_x.at(-1), y, 0]);
    this.static.add(segments(lines, 0x30363d));
    this.static.add(label("workspace grid", [area.x[1] + 0.02, area.y[0], 0.01], "#8893a2"));
  }

  // Rebuilt only when the scene changes (names, positions, states, target).
  setObjects(scene, target) {
    const key = JSON.stringify([scene?.objects, target]);
    if (key === this.objectsKey) return;
    this.objectsKey = key;
    this.changed = true;
    release(this.objects);
    for (const obj of scene?.objects || []) {
      this.objects.add(objectMesh(obj, obj.name === target, this.opensAwayBelowX));
    }
  }

  // Everything that moves every frame.
  setDynamic(s) {
    release(this.dynamic);
    this.changed = true;
    const tcp = s.robot?.tcp || s.scene?.robot?.tcp;
    const joints = s.robot?.joints;
    if (joints?.length === 7) this.addArm(joints, s.robot.kinematics === false);
    else delete this.canvas.dataset.arm;
    if (tcp) this.addGripper(tcp, s.robot?.gripper_width ?? (s.scene?.robot?.gripper_open ? 0.08 : 0.0),
      joints?.length !== 7);
    for (const hand of s.hands?.hands || []) this.addHand(hand, s.pointing);
    if (s.gaze) {
      this.dynamic.add(sphere(s.gaze.point, 0.012, 0xff7b72));
      this.dynamic.add(label(`gaze (${s.gaze.source})`, add(s.gaze.point, [0, 0, 0.02]), "#ff7b72"));
    }
    if (s.focus) {
      const ring = new THREE.Mesh(new THREE.TorusGeometry(0.03, 0.003, 8, 32),
        new THREE.MeshBasicMaterial({ color: 0xe3b341 }));
      ring.position.set(...s.focus);
      this.dynamic.add(ring, label("focus", add(s.focus, [0, 0, 0.035]), "#e3b341"));
    }
  }

  // The arm's links between its joint frames, posed by the measured joints. A robot without
  // kinematics (dry-robot, franka's dry run: `kinematics: false`) publishes the ready posture:
  // drawn faded and labelled nominal. The canvas's data-arm says what was drawn (for tests).
  addArm(joints, nominal) {
    const points = pandaLinkPoints(joints);
    const material = () => new THREE.MeshStandardMaterial({ color: 0xd0d4da, metalness: 0.2,
      transparent: nominal, opacity: nominal ? 0.3 : 1.0 });
    for (let i = 1; i < points.length; i++) {
      const link = cylinderBetween(points[i - 1], points[i], LINK_RADIUS, material());
      if (link) this.dynamic.add(link);
    }
    for (const p of points.slice(1, -1)) {
      const ball = new THREE.Mesh(new THREE.SphereGeometry(JOINT_RADIUS, 16, 12), material());
      ball.position.set(...p);
      this.dynamic.add(ball);
    }
    if (nominal) this.dynamic.add(label("arm: nominal pose (no kinematics)", add(points[5], [0, 0, 0.08]), "#8893a2"));
    this.canvas.dataset.arm = JSON.stringify({ pose: nominal ? "nominal" : "measured",
      tcp: points.at(-1).map((v) => Math.round(v * 1e4) / 1e4), links: points.length - 1 });
  }

  // The TCP and the fingers; `line`: a line from the base stands for an arm not drawn.
  addGripper(tcp, width, line = true) {
    const metal = new THREE.MeshStandardMaterial({ color: 0xeeeeee, metalness: 0.3 });
    if (line) {
      this.dynamic.add(segments([[0, 0, 0.06], [0, 0, 0.33], [0, 0, 0.33], [tcp[0], tcp[1], tcp[2] + 0.1],
        [tcp[0], tcp[1], tcp[2] + 0.1], tcp], 0x6e7681));
    }
    const half = Math.max(0.004, Math.min(width, 0.08) / 2);
    for (const side of [-1, 1]) {
      const finger = new THREE.Mesh(new THREE.BoxGeometry(0.01, 0.008, 0.04), metal);
      finger.position.set(tcp[0], tcp[1] + side * half, tcp[2] + 0.01);
      this.dynamic.add(finger);
    }
    this.dynamic.add(sphere(tcp, 0.008, 0x3fb950));
    this.dynamic.add(label(`TCP ${(width * 1000).toFixed(0)} mm`, add(tcp, [0, 0, 0.07]), "#3fb950"));
  }

  addHand(hand, pointing) {
    const colour = HAND_COLOURS[hand.side] ?? 0xffffff;
    const lines = [];
    for (const finger of hand.fingers) {
      lines.push(hand.wrist, finger[0]);
      for (let i = 0; i < 4; i++) lines.push(finger[i], finger[i + 1]);
    }
    for (let f = 1; f < 4; f++) lines.push(hand.fingers[f][1], hand.fingers[f + 1][1]);
    this.dynamic.add(segments(lines, colour));
    this.dynamic.add(sphere(hand.palm, 0.01, colour));
    this.dynamic.add(label(`${hand.side} hand`, add(hand.palm, [0, 0, 0.04]), "#" + colour.toString(16).padStart(6, "0")));
    if (pointing) this.addRay(hand);
  }

  // The index finger's ray, from its tip along its last bone, to the table (or 1.5 m).
  addRay(hand) {
    const tip = hand.fingers[1][4], prev = hand.fingers[1][3];
    const d = [tip[0] - prev[0], tip[1] - prev[1], tip[2] - prev[2]];
    const n = Math.hypot(...d) || 1;
    let len = 1.5;
    if (d[2] < -1e-6) len = Math.min(len, (-tip[2] / (d[2] / n)));
    const end = [tip[0] + d[0] / n * len, tip[1] + d[1] / n * len, tip[2] + d[2] / n * len];
    this.dynamic.add(segments([tip, end], 0xe3b341, true));
  }

  render() {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    if (this.canvas.width !== Math.round(w * this.renderer.getPixelRatio())) {
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / h; this.camera.updateProjectionMatrix();
      this.changed = true;
    }
    if (!this.changed) return;
    this.renderer.render(this.scene, this.camera);
    this.layOutLabels(w, h);
    this.changed = false;
  }

  // Every label's anchor projected onto the canvas; the label sits centred above its anchor,
  // unless another label is there already: then it moves up above that one. The lowest labels
  // are placed first, so a label only ever moves up, past each label it would cover once.
  layOutLabels(width, height) {
    const anchors = [];
    this.scene.updateMatrixWorld();
    this.scene.traverse((o) => { if (o.userData.label) anchors.push(o); });
    const point = new THREE.Vector3();
    const items = [];
    for (const anchor of anchors) {
      anchor.getWorldPosition(point).project(this.camera);
      if (point.z < -1 || point.z > 1) continue;  // behind the camera or past its far plane
      items.push({ ...anchor.userData.label, x: (point.x + 1) / 2 * width, y: (1 - point.y) / 2 * height });
    }
    const layer = this.labelLayer;
    while (layer.children.length < items.length) layer.append(document.createElement("span"));
    while (layer.children.length > items.length) layer.lastChild.remove();
    items.forEach((item, k) => {
      const el = layer.children[k];
      if (el.textContent !== item.text) el.textContent = item.text;
      el.style.color = item.colour;
    });
    const sizes = items.map((_, k) => [layer.children[k].offsetWidth, layer.children[k].offsetHeight]);
    const placed = [];
    for (const k of items.map((_, k) => k).sort((a, b) => items[b].y - items[a].y)) {
      const [w, h] = sizes[k];
      const box = { left: items[k].x - w / 2, top: items[k].y - h, width: w, height: h };
      for (let hit = placed.find((p) => overlap(p, box)); hit; hit = placed.find((p) => overlap(p, box)))
        box.top = hit.top - h - 1;
      placed.push(box);
      layer.children[k].style.transform = `translate(${Math.round(box.left)}px, ${Math.round(box.top)}px)`;
    }
  }
}

function overlap(a, b) {
  return a.left < b.left + b.width && b.left < a.left + a.width &&
    a.top < b.top + b.height && b.top < a.top + a.height;
}

// opensAwayBelowX: a drawer standing nearer the robot than this opens away from it (+x), the
// others towards it (-x); null when the workspace does not say (every drawer opens towards it).
function objectMesh(obj, isTarget, opensAwayBelowX = null) {
  const group = new THREE.Group();
  const s = obj.size, [x, y, z] = obj.position;
  const colour = isTarget ? TARGET : OBJECT_COLOURS[obj.type] ?? 0xffffff;
  const material = new THREE.MeshStandardMaterial({
    color: colour, emissive: isTarget ? 0x665500 : 0x000000, transparent: obj.type === "drawer",
    opacity: obj.type === "drawer" ? 0.75 : 1 });
  let mesh;
  if (obj.type === "cup") {
    mesh = new THREE.Mesh(new THREE.CylinderGeometry(s / 2, s * 0.4, s, 24, 1, !obj.full), material);
    mesh.rotation.x = Math.PI / 2;
    if (obj.full) {
      const fill = new THREE.Mesh(new THREE.CylinderGeometry(s * 0.46, s * 0.42, s * 0.7, 24),
        new THREE.MeshStandardMaterial({ color: 0x1f6feb }));
      fill.rotation.x = Math.PI / 2; fill.position.set(x, y, z - s * 0.1);
      group.add(fill);
    }
  } else {
    mesh = new THREE.Mesh(new THREE.BoxGeometry(s, s, s), material);
  }
  mesh.position.set(x, y, z);
  group.add(mesh);
  if (obj.type === "drawer" && (obj.open || (obj.opening ?? 0) > 0.01)) {
    const out = (obj.opening ?? 1) * 0.818 * s;  // how far the tray has slid out
    const way = opensAwayBelowX !== null && x < opensAwayBelowX ? 1 : -1;
    const tray = new THREE.Mesh(new THREE.BoxGeometry(out, s * 0.9, s * 0.3),
      new THREE.MeshStandardMaterial({ color: 0xadbac7 }));
    tray.position.set(x + way * (s / 2 + out / 2), y, z - s * 0.2);
    group.add(tray);
  }
  if (isTarget) {
    const ring = new THREE.Mesh(new THREE.RingGeometry(s * 0.75, s * 0.9, 40),
      new THREE.MeshBasicMaterial({ color: TARGET, side: THREE.DoubleSide }));
    ring.position.set(x, y, 0.002);
    group.add(ring);
  }
  const state = [obj.full ? "full" : "", obj.open ? "open" : "", obj.on ? `on ${obj.on}` : "",
    obj.inside ? `in ${obj.inside}` : ""].filter(Boolean).join(", ");
  group.add(label(obj.name + (state ? ` (${state})` : "") + (isTarget ? " ◀ target" : ""),
    [x, y, z + s / 2 + 0.035], isTarget ? "#ffe066" : "#dde3ea"));
  return group;
}

// Empties a group and frees its GPU buffers.
function release(group) {
  group.traverse((o) => { o.geometry?.dispose(); o.material?.dispose(); });
  group.clear();
}

function add(a, b) { return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]; }

// The base, the origins of joint frames 1..7, the flange and the TCP, in the base frame (m):
// each joint's frame is Rx(alpha) Tx(a) Rz(q) Tz(d) of the one before (modified DH).
export function pandaLinkPoints(joints) {
  let frame = new THREE.Matrix4();
  const points = [[0, 0, 0]];
  const along = (m, d) => new THREE.Vector3(0, 0, d).applyMatrix4(m).toArray();
  PANDA_DH.forEach(([a, d, alpha], i) => {
    const step = new THREE.Matrix4().makeRotationX(alpha)
      .multiply(new THREE.Matrix4().makeTranslation(a, 0, 0))
      .multiply(new THREE.Matrix4().makeRotationZ(joints[i]))
      .multiply(new THREE.Matrix4().makeTranslation(0, 0, d));
    frame = frame.multiply(step);
    points.push(along(frame, 0));
  });
  points.push(along(frame, FLANGE_D), along(frame, FLANGE_D + HAND_TCP_D));
  return points;
}

// A cylinder from a to b (null where they coincide: joints 1-2 and 5-6 share an origin).
function cylinderBetween(a, b, radius, material) {
  const from = new THREE.Vector3(...a), dir = new THREE.Vector3(...b).sub(from);
  const length = dir.length();
  if (length < 1e-4) { material.dispose(); return null; }
  const mesh = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, length, 16), material);
  mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), dir.clone().normalize());
  mesh.position.copy(from.addScaledVector(dir, 0.5));
  return mesh;
}

function sphere(p, r, colour) {
  const m = new THREE.Mesh(new THREE.SphereGeometry(r, 16, 12), new THREE.MeshBasicMaterial({ color: colour }));
  m.position.set(...p);
  return m;
}

function segments(points, colour, dashed = false) {
  const geometry = new THREE.BufferGeometry().setFromPoints(points.map((p) => new THREE.Vector3(...p)));
  const material = dashed ? new THREE.LineDashedMaterial({ color: colour, dashSize: 0.03, gapSize: 0.02 })
    : new THREE.LineBasicMaterial({ color: colour });
  const lines = new THREE.LineSegments(geometry, material);
  if (dashed) lines.computeLineDistances();
  return lines;
}

function rectangle(xs, ys, z, colour) {
  const [x0, x1] = xs, [y0, y1] = ys;
  return segments([[x0, y0, z], [x1, y0, z], [x1, y0, z], [x1, y1, z], [x1, y1, z], [x0, y1, z],
    [x0, y1, z], [x0, y0, z]], colour);
}

// A label: an invisible point in the scene that `layOutLabels` puts an HTML label on.
function label(text, position, colour) {
  const anchor = new THREE.Object3D();
  anchor.position.set(...position);
  anchor.userData.label = { text, colour };
  return anchor;
}
