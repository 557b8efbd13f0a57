// The replay page: draws the run that host-sim embedded as JSON (element #replay-data) with
// three.js. World frame: x forward, y left, z up (m), as in the simulator.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

const data = JSON.parse(document.getElementById('replay-data').textContent);
const times = data.t;
const duration = times[times.length - 1] - times[0];
const signal = (name) => data.signals[name];

const PART_COLOURS = {
  base: 0x4a5568, wheel: 0x1f2933, torso: 0xc9ced6, head: 0xe2e6ea, right_arm: 0xe07b39, left_arm: 0x3b82c4,
  link: 0xe07b39, pedestal: 0x4a5568, environment: 0xb08b5a, object: 0xf5f0e1,
};
const PART_NAMES = {
  base: 'mobile platform', wheel: 'wheels (leg lines to the platform)', torso: 'torso', head: 'head',
  right_arm: 'right arm', left_arm: 'left arm', link: 'arm links', pedestal: 'fixed base of the arm',
  environment: 'environment (table, wall, …)', object: 'object the hands work on',
};

// ---- renderer, camera, lights, floor ----
const view = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
view.prepend(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xeef1f5);
const camera = new THREE.PerspectiveCamera(40, 1, 0.05, 100);
camera.up.set(0, 0, 1);
const controls = new OrbitControls(camera, renderer.domElement);
scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f99, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(3, -4, 6);
scene.add(sun);
const fill = new THREE.DirectionalLight(0xffffff, 0.6);
fill.position.set(-4, 3, 2);
scene.add(fill);

// ---- swept-sphere volumes ----
const v3 = (p) => new THREE.Vector3(p[0], p[1], p[2]);

function sphereMesh(centre, radius, material) {
  const mesh = new THREE.Mesh(new THREE.SphereGeometry(radius, 24, 16), material);
  mesh.position.copy(centre);
  return mesh;
}

function cylinderMesh(a, b, radius, material) {
  const axis = new THREE.Vector3().subVectors(b, a);
  const mesh = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, axis.length(), 24, 1, true), material);
  mesh.position.addVectors(a, b).multiplyScalar(0.5);
  mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), axis.normalize());
  return mesh;
}

// A triangle swept by a sphere: the prism of the triangle thickened by ±radius, cylinders on its
// edges and spheres on its corners.
function prismMesh([a, b, c], radius, material) {
  const n = new THREE.Vector3().crossVectors(new THREE.Vector3().subVectors(b, a), new THREE.Vector3().subVectors(c, a));
  n.normalize().multiplyScalar(radius);
  const top = [a, b, c].map((p) => p.clone().add(n));
  const bottom = [a, b, c].map((p) => p.clone().sub(n));
  const faces = [[top[0], top[1], top[2]], [bottom[0], bottom[2], bottom[1]]];
  for (let i = 0; i < 3; i += 1) {
    const j = (i + 1) % 3;
    faces.push([top[i], bottom[i], bottom[j]], [top[i], bottom[j], top[j]]);
  }
  const geometry = new THREE.BufferGeometry().setFromPoints(faces.flat());
  geometry.computeVertexNormals();
  return new THREE.Mesh(geometry, material);
}

function volumeObject(volume, material) {
  const points = volume.points.map(v3);
  const group = new THREE.Group();
  points.forEach((p) => group.add(sphereMesh(p, volume.radius, material)));
  for (let i = 0; points.length > 1 && i < points.length; i += 1) {
    const j = (i + 1) % points.length;
    if (points.length === 2 && i === 1) break;
    group.add(cylinderMesh(points[i], points[j], volume.radius, material));
  }
  if (points.length === 3) group.add(prismMesh(points, volume.radius, material));
  return group;
}

const materials = {};
for (const [part, colour] of Object.entries(PART_COLOURS)) {
  const environment = part === 'environment';
  materials[part] = new THREE.MeshStandardMaterial({
    color: colour, roughness: 0.6, metalness: 0.05, side: THREE.DoubleSide,
    transparent: environment, opacity: environment ? 0.55 : 1,
  });
}

const bodies = data.parents.map(() => {
  const group = new THREE.Group();
  scene.add(group);
  return group;
});
for (const volume of data.volumes) {
  if (volume.part === 'floor') continue; // drawn as the floor grid
  const object = volumeObject(volume, materials[volume.part] ?? materials.environment);
  object.userData.robotVolume = volume.body >= 0;
  if (volume.body < 0) scene.add(object);
  else bodies[volume.body].add(object);
}

// The links: a line from each body's origin to its parent's, and a dot at every joint.
const skeletonPositions = new Float32Array(data.parents.length * 6);
const skeletonGeometry = new THREE.BufferGeometry();
skeletonGeometry.setAttribute('position', new THREE.BufferAttribute(skeletonPositions, 3));
scene.add(new THREE.LineSegments(skeletonGeometry, new THREE.LineBasicMaterial({ color: 0x1f2933 })));
const jointMaterial = new THREE.MeshStandardMaterial({ color: 0x1f2933 });
bodies.forEach((body) => body.add(new THREE.Mesh(new THREE.SphereGeometry(0.025, 12, 8), jointMaterial)));

// Floor: a light plane with a 0.5 m grid.
const floor = new THREE.Mesh(new THREE.PlaneGeometry(40, 40), new THREE.MeshStandardMaterial({ color: 0xf7f8fa, roughness: 1 }));
floor.position.z = -0.002;
scene.add(floor);
const grid = new THREE.GridHelper(20, 40, 0xc3cad3, 0xd5dae1);
grid.rotation.x = Math.PI / 2;
scene.add(grid);

// ---- paths, goals, forces ----
// A path through the points given as coordinate arrays (null: undefined, skipped): a tube of
// 6 mm radius, or a thin dashed line.
function pathLine(xs, ys, zs, colour, dashed, radius = 0.006) {
  const points = [];
  xs.forEach((x, i) => { if (x !== null && ys[i] !== null && zs[i] !== null) points.push(new THREE.Vector3(x, ys[i], zs[i])); });
  if (points.length < 2) return;
  if (dashed) {
    const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(points),
      new THREE.LineDashedMaterial({ color: colour, dashSize: 0.03, gapSize: 0.02 }));
    line.computeLineDistances();
    scene.add(line);
    return;
  }
  const curve = new THREE.CatmullRomCurve3(points);
  scene.add(new THREE.Mesh(new THREE.TubeGeometry(curve, Math.min(2000, 4 * points.length), radius, 8),
    new THREE.MeshStandardMaterial({ color: colour, roughness: 0.5 })));
}

// An arrow of a shaft and a cone along +y, scaled to its length by `setArrow`.
function forceArrow(colour) {
  const material = new THREE.MeshStandardMaterial({ color: colour, roughness: 0.4 });
  const shaft = new THREE.Mesh(new THREE.CylinderGeometry(0.012, 0.012, 1, 12), material);
  const head = new THREE.Mesh(new THREE.ConeGeometry(0.035, 0.09, 16), material);
  const arrow = new THREE.Group();
  arrow.add(shaft, head);
  arrow.userData = { shaft, head };
  arrow.visible = false;
  scene.add(arrow);
  return arrow;
}

// Places `arrow` so that it ends at `tip` and points along `force`, 1 cm per N.
function setArrow(arrow, tip, force) {
  const length = force.length() * 0.01;
  const direction = force.clone().normalize();
  const { shaft, head } = arrow.userData;
  const shaftLength = Math.max(length - 0.09, 0.001);
  shaft.scale.set(1, shaftLength, 1);
  shaft.position.set(0, shaftLength / 2, 0);
  head.position.set(0, shaftLength + 0.045, 0);
  arrow.position.copy(tip).addScaledVector(direction, -length);
  arrow.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), direction);
}

const legend = [];
// A path given as coordinate arrays [[x…], [y…], [z…]] (null: undefined).
const pathPoint = (path, i) => (path[0][i] === null || path[1][i] === null || path[2][i] === null
  ? null : new THREE.Vector3(path[0][i], path[1][i], path[2][i]));
// The service tasks press on surfaces (columns contact.<surface>.force); the replay draws a patch of
// the surface where and while a hand presses on it.
const hasSurfaces = Object.keys(data.signals).some((n) => /^contact\..*\.force$/.test(n));
const HAND_COLOURS = [0xc2410c, 0x1d4ed8];
const hands = data.hands.map((hand, k) => {
  const colour = HAND_COLOURS[k % HAND_COLOURS.length];
  pathLine(...hand.path, colour, false);
  if (hand.goal) pathLine(...hand.goal, colour, true);
  const goalMarker = new THREE.Mesh(new THREE.SphereGeometry(0.04, 16, 12),
    new THREE.MeshBasicMaterial({ color: colour, wireframe: true }));
  scene.add(goalMarker);
  goalMarker.visible = Boolean(hand.goal);
  const arrow = forceArrow(0xd61f69);
  // The touched surface, drawn where and while the hand presses on it (normal along the force).
  const surface = new THREE.Mesh(new THREE.CircleGeometry(0.08, 32), materials.environment);
  surface.visible = false;
  scene.add(surface);
  legend.push([colour, hand.goal ? `${hand.label} path (solid) and its goal (dashed, wire ball)` : `${hand.label} path`]);
  return { ...hand, goalMarker, arrow, surface };
});
if (hands.some((h) => h.force)) legend.push([0xd61f69, 'force on a hand (push or contact), 1 cm per N']);
if (hasSurfaces) legend.push([PART_COLOURS.environment, 'contact surface, drawn where a hand presses on it']);
if (data.platform) {
  // Thicker than the hands' paths: seen from afar, on the floor.
  pathLine(data.platform[0], data.platform[1], data.platform[0].map(() => 0.02), 0x2f855a, false, 0.02);
  legend.push([0x2f855a, 'platform centre path']);
}
const parts = new Set(data.volumes.map((v) => v.part));
for (const [part, colour] of Object.entries(PART_COLOURS)) if (parts.has(part)) legend.push([colour, PART_NAMES[part]]);

// ---- camera framing: everything that moves and the environment, seen from the front left ----
const box = new THREE.Box3();
for (const volume of data.volumes) {
  if (volume.body < 0 && volume.part !== 'floor') volume.points.forEach((p) => box.expandByPoint(v3(p)));
}
data.bodies.forEach((placements) => {
  for (let k = 0; k < placements.length; k += 7) box.expandByPoint(new THREE.Vector3(placements[k], placements[k + 1], placements[k + 2]));
});
hands.forEach((h) => h.path[0].forEach((_, i) => { const p = pathPoint(h.path, i); if (p) box.expandByPoint(p); }));
box.expandByPoint(new THREE.Vector3(box.min.x, box.min.y, 0));
const size = box.getSize(new THREE.Vector3()).length();
// Aim between the middle of the scene and the middle of the hands' paths, where the work is.
const centre = box.getCenter(new THREE.Vector3());
const handBox = new THREE.Box3();
hands.forEach((h) => h.path[0].forEach((_, i) => { const p = pathPoint(h.path, i); if (p) handBox.expandByPoint(p); }));
if (!handBox.isEmpty()) centre.lerp(handBox.getCenter(new THREE.Vector3()), 0.5);
controls.target.copy(centre);
// A robot moving in the x–z plane (the planar arms) is seen from the side; any other from the
// side of the hand that travels further, slightly from the front and above, unless the scenario
// places the camera itself (`view`: from the centre to the camera, m).
const planar = box.max.y - box.min.y < 0.2;
const travel = (h) => h.path[0].reduce((sum, _, i) => {
  const [a, b] = [pathPoint(h.path, i - 1), pathPoint(h.path, i)];
  return i === 0 || !a || !b ? sum : sum + a.distanceTo(b);
}, 0);
const leftMovesMore = hands.length === 2 && travel(hands[1]) > travel(hands[0]);
const side = leftMovesMore ? 1 : -1;
const direction = data.view ? new THREE.Vector3(...data.view)
  : planar ? new THREE.Vector3(0.25, -1, 0.2) : new THREE.Vector3(0.6, side, 0.45);
if (data.view) camera.position.copy(centre).add(direction);
else camera.position.copy(centre).add(direction.normalize().multiplyScalar(size * (planar ? 1.5 : 1.3) + 2.2));

// ---- side panel ----
document.title = `${data.scenario} replay`;
document.getElementById('title').textContent = data.scenario;
document.getElementById('description').textContent = data.description;
const claims = document.getElementById('claims');
for (const [list, css, mark] of [[data.passed_claims, 'pass', '✔'], [data.failed_claims, 'fail', '✘']]) {
  for (const claim of list) {
    const item = document.createElement('li');
    item.className = css;
    item.textContent = `${mark} ${claim}`;
    claims.append(item);
  }
}
document.getElementById('legend').innerHTML = legend
  .map(([c, text]) => `<div><span class="key" style="background:#${c.toString(16).padStart(6, '0')}"></span>${text}</div>`)
  .join('');

// Levels whose storage is not zero throughout (levels the hierarchy uses).
const levels = Object.keys(data.signals).filter((n) => /^S\d+$/.test(n) && signal(n).some((v) => v !== 0));
const MODES = ['Normal', 'Hold', 'Brake'];
const distance = (a, b) => (a && b ? a.distanceTo(b) : null);
const rows = [
  ...hands.filter((h) => h.goal).map((h) => [`${h.label}: distance to its goal (mm)`,
    (i) => distance(pathPoint(h.path, i), pathPoint(h.goal, i)), 1e3]),
  ...levels.map((n) => [`storage of level ${n.slice(1)} (J)`, (i) => signal(n)[i], 1]),
  ['smallest collision distance (mm)', (i) => signal('min_distance')?.[i] ?? null, 1e3],
  ...hands.filter((h) => h.force).map((h) => [`force on the ${h.label} (N)`, (i) => pathPoint(h.force, i)?.length() ?? null, 1]),
  ['contact detected', (i) => (signal('contact') ? (signal('contact')[i] ? 'yes' : 'no') : null), 1],
  ['output mode', (i) => (signal('mode') ? MODES[signal('mode')[i]] ?? '?' : null), 1],
].filter(([, value]) => value(0) !== null && value(0) !== undefined);
const table = document.getElementById('signals');
const cells = rows.map(([label]) => {
  const row = table.insertRow();
  row.insertCell().textContent = label;
  return row.insertCell();
});

// ---- story: the events of the run as marks on the time slider, a caption and a list ----
const events = data.events;
const marks = document.getElementById('marks');
const story = document.getElementById('story');
const caption = document.getElementById('caption');
const fraction = (t) => (duration > 0 ? (t - times[0]) / duration : 0);
const eventItems = events.map((event) => {
  const mark = document.createElement('span');
  mark.className = event.phase ? 'mark phase' : 'mark';
  mark.style.left = `${100 * fraction(event.t)}%`;
  mark.title = `${event.t.toFixed(2)} s: ${event.text}`;
  marks.append(mark);
  const item = document.createElement('li');
  if (event.phase) item.className = 'phase';
  item.innerHTML = `<a href="#t=${event.t.toFixed(2)}">${event.t.toFixed(2)} s</a> ${event.text}`;
  story.append(item);
  return item;
});
if (events.length === 0) story.innerHTML = '<li>none: the scenario names no phases, and the signals show no push, contact, goal step or platform motion</li>';

// The caption names the phase the run is in (the scenario's latest phase before `t`) and the
// latest event found in the signals in the 1.5 s before `t`.
function showStory(t) {
  const past = events.filter((e) => e.t <= t + 1e-9);
  const phase = past.filter((e) => e.phase).slice(-1);
  const recent = past.filter((e) => !e.phase && e.t > t - 1.5).slice(-1);
  const shown = [...phase, ...recent];
  caption.innerHTML = shown.map((e) => `<div>${e.t.toFixed(2)} s: ${e.text}</div>`).join('');
  caption.style.visibility = shown.length > 0 ? 'visible' : 'hidden';
  events.forEach((e, k) => eventItems[k].classList.toggle('past', e.t <= t + 1e-9));
}

// ---- playback ----
const slider = document.getElementById('slider');
const timeLabel = document.getElementById('time');
const playButton = document.getElementById('play');
const speed = document.getElementById('speed');
const volumesToggle = document.getElementById('volumes');
let time = times[0];
let playing = true;

const frameAt = (t) => {
  let lo = 0;
  let hi = times.length - 1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (times[mid] <= t) lo = mid; else hi = mid - 1;
  }
  return lo;
};

function show(i) {
  const placements = data.bodies[i];
  bodies.forEach((body, b) => {
    const k = 7 * b;
    body.position.set(placements[k], placements[k + 1], placements[k + 2]);
    body.quaternion.set(placements[k + 3], placements[k + 4], placements[k + 5], placements[k + 6]);
  });
  data.parents.forEach((parent, b) => {
    const from = parent < 0 ? b : parent;
    for (let a = 0; a < 3; a += 1) {
      skeletonPositions[6 * b + a] = placements[7 * from + a];
      skeletonPositions[6 * b + 3 + a] = placements[7 * b + a];
    }
  });
  skeletonGeometry.attributes.position.needsUpdate = true;
  for (const h of hands) {
    const goal = h.goal ? pathPoint(h.goal, i) : null;
    if (goal) h.goalMarker.position.copy(goal);
    const force = h.force ? pathPoint(h.force, i) ?? new THREE.Vector3() : new THREE.Vector3();
    const tip = pathPoint(h.path, i);
    h.arrow.visible = tip !== null && force.length() > 0.5;
    if (h.arrow.visible) setArrow(h.arrow, tip, force);
    h.surface.visible = hasSurfaces && h.arrow.visible;
    if (h.surface.visible) {
      h.surface.position.copy(tip);
      h.surface.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), force.clone().normalize());
    }
  }
  showStory(times[i]);
  rows.forEach(([, value, scale], r) => {
    const v = value(i);
    cells[r].textContent = typeof v === 'number' ? (v * scale).toFixed(scale === 1 ? 2 : 1) : (v ?? '–');
  });
}

function seek(t) {
  time = Math.min(Math.max(t, times[0]), times[times.length - 1]);
  slider.value = duration > 0 ? (time - times[0]) / duration : 0;
  timeLabel.textContent = `${time.toFixed(2)} / ${times[times.length - 1].toFixed(2)} s`;
  show(frameAt(time));
}

function setPlaying(on) {
  playing = on;
  playButton.textContent = on ? 'Pause' : 'Play';
  if (!on) history.replaceState(null, '', `#t=${time.toFixed(2)}`);
}

function timeFromHash() {
  const match = /t=([0-9.]+)/.exec(location.hash);
  return match ? Number(match[1]) : null;
}

playButton.addEventListener('click', () => {
  if (!playing && time >= times[times.length - 1]) seek(times[0]);
  setPlaying(!playing);
});
slider.addEventListener('input', () => { setPlaying(false); seek(times[0] + Number(slider.value) * duration); });
volumesToggle.addEventListener('change', () => {
  bodies.forEach((body) => body.children.forEach((c) => { if (c.userData.robotVolume) c.visible = volumesToggle.checked; }));
});
window.addEventListener('hashchange', () => {
  const t = timeFromHash();
  if (t !== null) { setPlaying(false); seek(t); }
});

function resize() {
  const { clientWidth: w, clientHeight: h } = view;
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

const start = timeFromHash();
if (start !== null) { seek(start); setPlaying(false); } else seek(times[0]);

let last = performance.now();
renderer.setAnimationLoop((now) => {
  const dt = (now - last) / 1000;
  last = now;
  if (playing) {
    seek(time + dt * Number(speed.value));
    if (time >= times[times.length - 1]) setPlaying(false);
  }
  controls.update();
  renderer.render(scene, camera);
  window.replayShownTime = time;
});
