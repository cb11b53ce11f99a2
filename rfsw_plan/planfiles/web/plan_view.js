// plan.html: the plan in 3-D (rfsw_plan/planfiles/page3d.py writes the data this draws).
// Base frame of the robot, z up, millimetres. Everything is inline: no request leaves the page.
import * as THREE from "three";
import { OrbitControls } from "three/OrbitControls";

const D = JSON.parse(document.getElementById("plan-data").textContent);
const N = D.n, NJ = D.chain_axis.length / 3;
const $ = (id) => document.getElementById(id);
const v3 = (a, k) => new THREE.Vector3(a[3 * k], a[3 * k + 1], a[3 * k + 2]);

// -- renderer, camera, light ---------------------------------------------------------------
const canvas = $("scene");
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xffffff);
const camera = new THREE.PerspectiveCamera(40, 1, 1, 1e6);
camera.up.set(0, 0, 1);
scene.add(new THREE.HemisphereLight(0xffffff, 0x666666, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(2000, -3000, 5000);
scene.add(sun);
const controls = new OrbitControls(camera, canvas);

// -- sizes ---------------------------------------------------------------------------------
const seamPts = [];
for (let k = 0; k < N; k++) seamPts.push(v3(D.seam, k));
const seamBox = new THREE.Box3().setFromPoints(seamPts);
const seamMid = seamBox.getCenter(new THREE.Vector3());
const seamLen = Math.max(seamBox.getSize(new THREE.Vector3()).length(), 50);
const reach = Math.max(seamMid.length(), 500);
const R = 0.018 * reach;  // link radius [mm]

// -- robot: links from the kinematic model, joints, spindle ----------------------------------
const linkMat = new THREE.MeshStandardMaterial({ color: 0xf2a900, roughness: 0.6 });
const jointMat = new THREE.MeshStandardMaterial({ color: 0x555555, roughness: 0.5 });
const toolMat = new THREE.MeshStandardMaterial({ color: 0x8c9bab, roughness: 0.4 });
const cyl = new THREE.CylinderGeometry(1, 1, 1, 24);
function segment(mat, r) {
  const m = new THREE.Mesh(cyl, mat);
  m.userData.r = r;
  scene.add(m);
  return m;
}
const Y = new THREE.Vector3(0, 1, 0);
function place(m, a, b) {
  const d = new THREE.Vector3().subVectors(b, a);
  const L = d.length();
  m.visible = L > 1e-3;
  if (!m.visible) return;
  m.position.copy(a).addScaledVector(d, 0.5);
  m.quaternion.setFromUnitVectors(Y, d.divideScalar(L));
  m.scale.set(m.userData.r, L, m.userData.r);
}
const links = [], joints = [];
for (let i = 0; i < NJ; i++) {
  links.push([segment(linkMat, R), segment(linkMat, R)]);
  joints.push(segment(jointMat, 1.35 * R));
}
const base = segment(jointMat, 2.2 * R);
place(base, new THREE.Vector3(0, 0, 0), new THREE.Vector3(0, 0, 0.25 * R * 4));
const flangeLink = segment(linkMat, 0.8 * R);
const spindle = segment(toolMat, 1.6 * R);
const pin = segment(jointMat, 0.25 * R);

function frame(k, i) {  // joint frame i of sample k: position, rotation
  const p = v3(D.link_pos, k * NJ + i);
  const q = D.link_quat.slice(4 * (k * NJ + i), 4 * (k * NJ + i) + 4);
  return [p, new THREE.Quaternion(q[0], q[1], q[2], q[3])];
}
const tcpLocal = v3(D.chain_tcp_pos, 0);
const tcpQ = new THREE.Quaternion(...D.chain_tcp_quat);
const poseTcp = new THREE.Vector3();
function poseRobot(k) {
  let pp = new THREE.Vector3(0, 0, 0), pq = new THREE.Quaternion();
  for (let i = 0; i < NJ; i++) {
    const [p, q] = frame(k, i);
    const corner = v3(D.chain_corner, i).applyQuaternion(pq).add(pp);
    place(links[i][0], pp, corner);
    place(links[i][1], corner, p);
    const ax = v3(D.chain_axis, i).applyQuaternion(q).multiplyScalar(1.6 * R);
    place(joints[i], p.clone().sub(ax), p.clone().add(ax));
    pp = p; pq = q;
  }
  const tcp = tcpLocal.clone().applyQuaternion(pq).add(pp);
  const z = new THREE.Vector3(0, 0, 1).applyQuaternion(pq.clone().multiply(tcpQ));
  const tl = Math.max(tcpLocal.length(), 8 * R);
  const top = tcp.clone().addScaledVector(z, -0.75 * tl);
  const body = tcp.clone().addScaledVector(z, -0.12 * tl);
  place(flangeLink, pp, top);
  place(spindle, top, body);
  place(pin, body, tcp);
  poseTcp.copy(tcp);
}

// -- plate, seam, window band, paths -----------------------------------------------------------
const T = new THREE.Vector3(...D.tangent), Nrm = new THREE.Vector3(...D.normal);
const L = new THREE.Vector3().crossVectors(Nrm, T);
const plateW = Math.max(0.5 * seamLen, 300), plateL = seamLen + 200, plateH = 10;
const plate = new THREE.Mesh(new THREE.BoxGeometry(plateL, plateW, plateH),
  new THREE.MeshStandardMaterial({ color: 0xc8ccd2, transparent: true, opacity: 0.55 }));
plate.quaternion.setFromRotationMatrix(new THREE.Matrix4().makeBasis(T, L, Nrm));
plate.position.copy(seamMid).addScaledVector(Nrm, -plateH / 2 - 0.5);
scene.add(plate);
const seamLine = new THREE.Line(new THREE.BufferGeometry().setFromPoints(seamPts),
  new THREE.LineBasicMaterial({ color: 0x222222 }));
scene.add(seamLine);

const inContact = (k) => D.margin[k] !== null;
const bandGeo = new THREE.BufferGeometry();
const band = new THREE.Mesh(bandGeo, new THREE.MeshBasicMaterial(
  { color: 0x2ca02c, transparent: true, opacity: 0.35, side: THREE.DoubleSide, depthWrite: false }));
scene.add(band);
const tcpGeo = new THREE.BufferGeometry(), pinGeo = new THREE.BufferGeometry();
const tcpLine = new THREE.Line(tcpGeo, new THREE.LineBasicMaterial({ color: 0xff7f0e }));
const pinLine = new THREE.Line(pinGeo, new THREE.LineBasicMaterial({ vertexColors: true }));
const pinDots = new THREE.Points(pinGeo, new THREE.PointsMaterial(
  { size: 5, sizeAttenuation: false, vertexColors: true }));
scene.add(tcpLine, pinLine, pinDots);
const colours = [];
for (let k = 0; k < N; k++) {
  const c = new THREE.Color(D.colour[k]);
  colours.push(c.r, c.g, c.b);
}
pinGeo.setAttribute("color", new THREE.Float32BufferAttribute(colours, 3));

let mag = 50;
const magnified = (off, k) => v3(D.target, k).addScaledVector(v3(off, k), mag);
function drawPaths() {
  const tp = [], pp = [], bv = [];
  for (let k = 0; k < N; k++) {
    const a = magnified(D.tcp_off, k), b = magnified(D.pin_off, k);
    tp.push(a.x, a.y, a.z);
    pp.push(b.x, b.y, b.z);
    if (inContact(k)) {
      const s = v3(D.target, k), l = v3(D.lat, k);
      const lo = s.clone().addScaledVector(l, mag * D.window[0]);
      const hi = s.clone().addScaledVector(l, mag * D.window[1]);
      bv.push(lo, hi);
    }
  }
  tcpGeo.setAttribute("position", new THREE.Float32BufferAttribute(tp, 3));
  pinGeo.setAttribute("position", new THREE.Float32BufferAttribute(pp, 3));
  const pos = [], index = [];
  bv.forEach((p) => pos.push(p.x, p.y, p.z));
  for (let j = 0; j + 3 < bv.length; j += 2) index.push(j, j + 1, j + 2, j + 1, j + 3, j + 2);
  bandGeo.setAttribute("position", new THREE.Float32BufferAttribute(pos, 3));
  bandGeo.setIndex(index);
  for (const g of [tcpGeo, pinGeo, bandGeo]) g.computeBoundingSphere();
}

// -- the selected sample: markers, force and deflection arrows ---------------------------------
const ball = (c, r) => {
  const m = new THREE.Mesh(new THREE.SphereGeometry(r, 20, 14),
    new THREE.MeshBasicMaterial({ color: c, depthTest: false }));
  m.renderOrder = 2;
  scene.add(m);
  return m;
};
const pinMark = ball(0x000000, 0.3 * R), tcpMark = ball(0xff7f0e, 0.25 * R);
const worstMark = new THREE.Mesh(new THREE.TorusGeometry(0.5 * R, 0.08 * R, 10, 40),
  new THREE.MeshBasicMaterial({ color: 0xd62728 }));
scene.add(worstMark);
const forceArrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, 0x1f77b4);
const deflArrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, 0x9467bd);
scene.add(forceArrow, deflArrow);
let fmax = 1;
for (let k = 0; k < N; k++) fmax = Math.max(fmax, v3(D.force, k).length());
const fscale = 0.12 * reach / fmax;  // mm of arrow per N
function arrow(a, from, vec) {
  const L = vec.length();
  a.visible = L > 1e-6;
  if (!a.visible) return;
  a.position.copy(from);
  a.setDirection(vec.clone().divideScalar(L));
  a.setLength(L, Math.min(0.3 * L, 1.2 * R), Math.min(0.15 * L, 0.6 * R));
}

// -- controls, readout ---------------------------------------------------------------------
const slider = $("slider"), magIn = $("mag");
slider.max = String(N - 1);
magIn.value = String(mag);
$("mag-value").textContent = String(mag);
$("title").textContent = D.title;
$("verdict").textContent = D.verdict;
$("depth-note").textContent = D.depth_note;
$("cbar").style.background = "linear-gradient(90deg," + D.cbar.join(",") + ")";
$("cbar-lo").textContent = "0 mm";
$("cbar-hi").textContent = ((D.window[1] - D.window[0]) / 2).toFixed(2) + " mm";
const jump = $("phase-jump");
D.phases.forEach((p, j) => {
  const o = document.createElement("option");
  o.value = String(D.phase.indexOf(j));
  o.textContent = p;
  jump.appendChild(o);
});
const num = (v, d) => (v === null ? "\u2013" : v.toFixed(d));
let index = 0;
function select(k) {
  index = Math.max(0, Math.min(N - 1, k | 0));
  slider.value = String(index);
  jump.value = String(D.phase.indexOf(D.phase[index]));
  poseRobot(index);
  const p = magnified(D.pin_off, index), c = magnified(D.tcp_off, index);
  pinMark.position.copy(p);
  tcpMark.position.copy(c);
  arrow(forceArrow, p, v3(D.force, index).multiplyScalar(fscale));
  arrow(deflArrow, c, v3(D.defl, index).multiplyScalar(mag));
  $("ro-row").textContent = String(D.row[index]);
  $("ro-t").textContent = num(D.t[index], 3);
  $("ro-s").textContent = num(D.s[index], 3);
  $("ro-phase").textContent = D.phases[D.phase[index]];
  $("ro-lat").textContent = num(D.e_lat[index], 4);
  $("ro-depth").textContent = num(D.e_depth[index], 4);
  $("ro-margin").textContent = num(D.margin[index], 4);
  render();
}
function setMag(m) {
  mag = Math.max(1, Math.min(200, m | 0));
  $("mag-value").textContent = String(mag);
  drawPaths();
  if (D.worst !== null) worstMark.position.copy(magnified(D.pin_off, D.worst));
  select(index);
}
slider.addEventListener("input", () => select(Number(slider.value)));
magIn.addEventListener("input", () => setMag(Number(magIn.value)));
jump.addEventListener("change", () => select(Number(jump.value)));
const worstBtn = $("worst");
if (D.worst === null) {
  worstBtn.disabled = true;
  worstMark.visible = false;
} else {
  worstBtn.textContent = "worst sample (margin " + num(D.margin[D.worst], 3) + " mm)";
  worstBtn.addEventListener("click", () => select(D.worst));
  $("worst-note").textContent = "Worst sample: sample " + D.row[D.worst] +
    " (data row " + D.row[D.worst] + " of waypoints.csv, the first sample = 1), t = " +
    num(D.t[D.worst], 3) + " s, " + D.phases[D.phase[D.worst]] + " (red ring).";
}
let timer = null;
$("play").addEventListener("click", () => {
  if (timer !== null) {
    clearInterval(timer);
    timer = null;
    $("play").innerHTML = "&#9654; play";
    return;
  }
  if (index >= N - 1) select(0);
  $("play").innerHTML = "&#10074;&#10074; pause";
  timer = setInterval(() => {
    if (index >= N - 1) $("play").click();
    else select(index + 1);
  }, 40);
});

// -- views ---------------------------------------------------------------------------------
function look(target, dist, from) {
  controls.target.copy(target);
  const dir = (from || new THREE.Vector3(0.9, -1.3, 0.8)).clone().normalize();
  camera.position.copy(target).addScaledVector(dir, dist);
  controls.update();
  render();
}
const wholeRobot = () => {
  const pts = [new THREE.Vector3(), ...seamPts, poseTcp];
  for (let i = 0; i < NJ; i++) pts.push(frame(index, i)[0]);
  const box = new THREE.Box3().setFromPoints(pts);
  look(box.getCenter(new THREE.Vector3()), 1.45 * box.getSize(new THREE.Vector3()).length());
};
// close to the seam the robot turns translucent, so that it hides none of the paths
function seeThrough(on) {
  for (const m of [linkMat, jointMat, toolMat]) {
    m.transparent = on;
    m.opacity = on ? 0.25 : 1;
    m.depthWrite = !on;
    m.needsUpdate = true;
  }
}
$("cam-robot").addEventListener("click", () => { seeThrough(false); wholeRobot(); });
// close to the seam: from the side and low, so that the spindle hides little of the paths
const side = L.clone().add(Nrm.clone().multiplyScalar(0.6)).addScaledVector(T, -0.5);
$("cam-seam").addEventListener("click", () => {
  seeThrough(true);
  look(seamMid, 1.6 * seamLen + 300, side);
});

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  render();
}
let frames = 0;
function render() {
  renderer.render(scene, camera);
  frames += 1;
}
controls.addEventListener("change", render);
window.addEventListener("resize", resize);

setMag(mag);
select(0);
resize();
wholeRobot();
// For scripts (and the page's tests): the state of the view.
window.planView = {
  ready: true, n: N, worst: D.worst, row: D.row,
  get index() { return index; },
  get frames() { return frames; },
  tcp: () => [poseTcp.x, poseTcp.y, poseTcp.z],
  select, setMag,
};
