// The 3-D residual view of the validation reports (rfsw_plan/planfiles/page3d.py,
// residual_section): one arrow per measured pose, from the nominal TCP along its residual
// (measured - predicted), magnified; one set of arrows per model (before / after an effect).
import * as THREE from "three";
import { OrbitControls } from "three/OrbitControls";

const D = JSON.parse(document.getElementById("residual-data").textContent);
const $ = (id) => document.getElementById(id);
const canvas = $("residual-scene");
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xffffff);
const camera = new THREE.PerspectiveCamera(40, 1, 1, 1e6);
camera.up.set(0, 0, 1);
const controls = new OrbitControls(camera, canvas);
const M = D.points.length / 3;
const P = (k) => new THREE.Vector3(D.points[3 * k], D.points[3 * k + 1], D.points[3 * k + 2]);
const pts = [];
for (let k = 0; k < M; k++) pts.push(P(k));
const box = new THREE.Box3().setFromPoints(pts);
const size = Math.max(box.getSize(new THREE.Vector3()).length(), 100);
const centre = box.getCenter(new THREE.Vector3());
scene.add(new THREE.AxesHelper(0.15 * size));
const dots = new THREE.Points(new THREE.BufferGeometry().setFromPoints(pts),
  new THREE.PointsMaterial({ color: 0x333333, size: 4, sizeAttenuation: false }));
scene.add(dots);
const grid = new THREE.GridHelper(2 * size, 20, 0xcccccc, 0xe5e5e5);
grid.rotation.x = Math.PI / 2;
grid.position.set(centre.x, centre.y, box.min.z);
scene.add(grid);

// one line segment per pose (the arrow's shaft) and a small cone (its head)
const lineGeo = new THREE.BufferGeometry();
const lines = new THREE.LineSegments(lineGeo, new THREE.LineBasicMaterial({ vertexColors: true }));
scene.add(lines);
const cone = new THREE.ConeGeometry(1, 1, 10);
cone.translate(0, -0.5, 0);
const heads = new THREE.InstancedMesh(cone, new THREE.MeshBasicMaterial(), M);
scene.add(heads);
let set = 0, mag = D.mag;
const Y = new THREE.Vector3(0, 1, 0);
function draw() {
  const v = D.sets[set].vectors, colour = new THREE.Color(D.sets[set].colour);
  const pos = [], col = [], m = new THREE.Matrix4(), q = new THREE.Quaternion();
  let shown = 0;
  for (let k = 0; k < M; k++) {
    const r = new THREE.Vector3(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
    const a = P(k), L = r.length() * mag;
    const b = a.clone().addScaledVector(r, mag);
    pos.push(a.x, a.y, a.z, b.x, b.y, b.z);
    col.push(colour.r, colour.g, colour.b, colour.r, colour.g, colour.b);
    if (L > 1e-9) {
      q.setFromUnitVectors(Y, r.clone().normalize());
      const h = Math.min(0.25 * L, 0.02 * size);
      m.compose(b, q, new THREE.Vector3(0.35 * h, h, 0.35 * h));
      shown += 1;
    } else m.makeScale(0, 0, 0);
    heads.setMatrixAt(k, m);
    heads.setColorAt(k, colour);
  }
  heads.instanceMatrix.needsUpdate = true;
  if (heads.instanceColor) heads.instanceColor.needsUpdate = true;
  lineGeo.setAttribute("position", new THREE.Float32BufferAttribute(pos, 3));
  lineGeo.setAttribute("color", new THREE.Float32BufferAttribute(col, 3));
  lineGeo.computeBoundingSphere();
  $("residual-readout").textContent = D.sets[set].label + ": " + D.sets[set].score +
    "; " + M + " arrows, x" + mag + " (1 mm of residual = " + mag + " mm drawn).";
  render();
  return shown;
}
function render() { renderer.render(scene, camera); }
const choice = $("residual-set");
D.sets.forEach((s, j) => {
  const o = document.createElement("option");
  o.value = String(j);
  o.textContent = s.label;
  choice.appendChild(o);
});
choice.addEventListener("change", () => { set = Number(choice.value); draw(); });
const magIn = $("residual-mag");
magIn.value = String(mag);
magIn.addEventListener("input", () => { mag = Number(magIn.value); draw(); });
function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  render();
}
controls.target.copy(centre);
camera.position.copy(centre).addScaledVector(new THREE.Vector3(0.9, -1.3, 0.8).normalize(), 1.6 * size);
controls.update();
controls.addEventListener("change", render);
window.addEventListener("resize", resize);
resize();
draw();
window.residualView = {
  ready: true, sets: D.sets.length,
  get set() { return set; },
  select: (j) => { set = j; choice.value = String(j); return draw(); },
};
