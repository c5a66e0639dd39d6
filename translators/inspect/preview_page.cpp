// SPDX-License-Identifier: GPL-3.0-or-later
// The preview's page: the collected data as JSON inside one self-contained HTML file, with the
// page's style and script and three.js inlined. What it may call: see preview.hpp.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "translators/inspect/preview.hpp"
#include "translators/inspect/three_js.hpp"

namespace xlate5 {

namespace {

// Six significant digits: enough to draw.
std::string num(double v) {
    if (!std::isfinite(v)) return "null";
    char b[32];
    std::snprintf(b, sizeof b, "%.6g", v);
    return b;
}

// A written joint value as written (up to 9 decimals, values up to 1e9: 12 significant digits
// and the decimals kept), so the page's joints and extremes are the file's and the report's.
std::string joint_num(double v) {
    if (!std::isfinite(v)) return "null";
    char b[40];
    std::snprintf(b, sizeof b, "%.12g", v);
    return b;
}

std::string html_text(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '<') o += "&lt;";
        else if (c == '>') o += "&gt;";
        else if (c == '&') o += "&amp;";
        else o += c;
    }
    return o;
}

// A JSON string inside a <script> element: quotes, backslashes and control bytes escaped, and
// '<' written as \u003c so no text can close the element.
std::string json_text(std::string_view s) {
    std::string o = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') o += '\\', o += c;
        else if (c == '<') o += "\\u003c";
        else if (static_cast<unsigned char>(c) < 0x20) {
            char b[8];
            std::snprintf(b, sizeof b, "\\u%04x", c);
            o += b;
        } else o += c;
    }
    return o + "\"";
}

const char* shape_name(PreviewBody::Shape s) {
    switch (s) {
        case PreviewBody::Shape::Box: return "box";
        case PreviewBody::Shape::Cylinder: return "cylinder";
        case PreviewBody::Shape::Cone: return "cone";
        case PreviewBody::Shape::Capsule: return "capsule";
        case PreviewBody::Shape::Sphere: return "sphere";
        case PreviewBody::Shape::Mesh: return "mesh";
    }
    return "";
}

const char* kind_name(PreviewMark::Kind kind) {
    switch (kind) {
        case PreviewMark::Kind::PoleCrossing: return "pole";
        case PreviewMark::Kind::Unwind: return "unwind";
        case PreviewMark::Kind::BranchChange: return "branch";
        case PreviewMark::Kind::Rezero: return "rezero";
        case PreviewMark::Kind::Slowed: return "slowed";
    }
    return "";
}

std::string matrix_json(const Eigen::Isometry3d& m) {
    std::string o = "[";
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) o += std::string(r || c ? "," : "") + num(m(r, c));
    return o + "]";
}

std::string chain_json(const std::vector<ChainElement>& chain) {
    std::string o = "[";
    for (std::size_t i = 0; i < chain.size(); ++i) {
        const auto& e = chain[i];
        o += i ? ",{" : "{";
        const auto v = [](const Eigen::Vector3d& x) { return "[" + num(x.x()) + "," + num(x.y()) + "," + num(x.z()) + "]"; };
        if (e.kind == ChainElement::Kind::Fixed) o += "\"k\":\"fixed\",\"m\":" + matrix_json(e.fixed);
        else if (e.kind == ChainElement::Kind::Linear) o += "\"k\":\"linear\",\"j\":" + std::to_string(e.joint) + ",\"axis\":" + v(e.axis);
        else o += "\"k\":\"rotary\",\"j\":" + std::to_string(e.joint) + ",\"axis\":" + v(e.axis) + ",\"point\":" + v(e.point);
        o += "}";
    }
    return o + "]";
}

const char* kStyle =
    "body{font-family:sans-serif;margin:12px}canvas{display:block;border:1px solid #ccc;margin:4px 0}"
    "#main{display:flex;gap:12px;align-items:flex-start}#side{width:330px;font-size:13px}#side ul{max-height:260px;overflow:auto;padding-left:18px}"
    "#side li button{font-size:12px;margin:1px 0}#linetext{font-family:monospace;background:#f4f4f4;padding:4px;word-break:break-all}"
    "#joints-now td{padding:0 6px}#controls label{margin-right:10px}#nogl{color:#a00}";

const char* kBody =
    "<div id=\"controls\"><label>Colour by <select id=\"colour\"><option value=\"tilt\">tilt</option><option value=\"dev\">deviation</option>"
    "<option value=\"feed\">feed</option></select></label><label><input type=\"checkbox\" id=\"axis\"> tool axis</label>"
    "<label><input type=\"checkbox\" id=\"machine\" checked> machine</label><label><input type=\"checkbox\" id=\"upto\"> path up to the scrubber</label>"
    "<button id=\"fit\">fit to part</button> <button id=\"worst\">worst deviation</button> <span id=\"legend\"></span></div>\n"
    "<div id=\"main\"><div><div id=\"view\"></div><p id=\"nogl\"></p>"
    "<div><button id=\"back\">&#9664;</button> <button id=\"play\">play</button> <button id=\"step\">&#9654;</button> "
    "<input type=\"range\" id=\"scrub\" min=\"0\" max=\"0\" value=\"0\" style=\"width:640px\"></div>"
    "<div id=\"linetext\"></div><table id=\"joints-now\"></table></div>\n"
    "<div id=\"side\"><b>Marks</b> (click one to go there)<ul id=\"marks\"></ul><b>Slowed to a joint's max_feed</b><ul id=\"slowed\"></ul>"
    "<b>Collisions</b> (--collision warn)<ul id=\"collisions\"></ul>"
    "<b>Re-routed travels</b> (lifted over what they would meet)<ul id=\"reroutes\"></ul>"
    "<b>Where the serial link lets the planner drain</b> (--baud)<ul id=\"drains\"></ul><b>Machine bodies</b> <span id=\"bodies-source\"></span>"
    "<ul id=\"bodies\"></ul></div></div>\n"
    "<div id=\"joints\"></div>\n<pre id=\"summary\" style=\"display:none\"></pre>\n";

// The page's script, on three.js and its OrbitControls (inlined above it).
const char* kScript = R"JS(
const D = JSON.parse(document.getElementById('data').textContent);
const KIND = {pole: {colour: '#d0d', text: 'pole crossing'}, unwind: {colour: '#f80', text: 'unwind (whole turns)'},
              branch: {colour: '#0a0', text: 'branch change (the other solution)'}, rezero: {colour: '#777', text: 're-zero (G92)'},
              slowed: {colour: '#c00', text: 'a joint at its max_feed'}};
const n = D.q.length, J = D.joints.length;
const summary = {three: THREE.REVISION, webgl: false, points: n, printed_segments: 0, travel_segments: 0, swings: D.swing.length,
                 bodies: 0, marks: {}, listed: {}, scrubber: null};
const mode = document.getElementById('colour');
const hash = new URLSearchParams(location.hash.slice(1));
if (location.hash === '#deviation' || hash.get('colour') === 'dev') mode.value = 'dev';
if (hash.get('colour') === 'feed') mode.value = 'feed';
function fraction(p) {
  if (mode.value === 'dev') return Math.min(1, p[8] / D.tolerance);
  if (mode.value === 'feed') return D.max_feed > 0 ? Math.min(1, p[9] / D.max_feed) : 0;
  return D.max_tilt > 0 ? Math.min(1, p[6] / D.max_tilt) : 0;
}
function legend() {
  document.getElementById('legend').textContent =
    (mode.value === 'dev' ? 'deviation: blue 0 \u2026 red ' + D.tolerance + ' mm (the tolerance) and beyond'
     : mode.value === 'feed' ? 'feed as written: blue 0 \u2026 red ' + D.max_feed + '/min'
     : 'tilt: blue 0\u00b0 \u2026 red ' + D.max_tilt.toFixed(1) + '\u00b0') + '; dashed: travel; axes red X, green Y, blue Z.';
}
// Forward kinematics of the chains, as the machine file states them (base -> plate, base -> tip).
function element(e, q) {
  const m = new THREE.Matrix4();
  if (e.k === 'fixed') { const a = e.m; m.set(a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], 0, 0, 0, 1); }
  else if (e.k === 'linear') m.makeTranslation(e.axis[0] * q[e.j], e.axis[1] * q[e.j], e.axis[2] * q[e.j]);
  else {
    const p = e.point, r = new THREE.Matrix4().makeRotationAxis(new THREE.Vector3(e.axis[0], e.axis[1], e.axis[2]).normalize(), q[e.j] * Math.PI / 180);
    m.makeTranslation(p[0], p[1], p[2]).multiply(r).multiply(new THREE.Matrix4().makeTranslation(-p[0], -p[1], -p[2]));
  }
  return m;
}
function frames(chain, q) {
  const out = [new THREE.Matrix4()];
  for (const e of chain) out.push(out[out.length - 1].clone().multiply(element(e, q)));
  return out;
}
function frameOf(name, F) {
  const [side, k] = name.split(':'), list = F[side];
  return list[k === undefined ? list.length - 1 : Number(k)];
}
const tips = D.pose.map(p => new THREE.Vector3(p[0], p[1], p[2]));
const framed = D.pose.some(p => p[7]) ? tips.filter((t, i) => D.pose[i][7]) : tips;
const box = new THREE.Box3().setFromPoints(framed.length ? framed : [new THREE.Vector3()]);
const size = Math.max(1, box.getSize(new THREE.Vector3()).length());

const holder = document.getElementById('view');
let renderer = null;
try { renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true}); } catch (e) { renderer = null; }
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xffffff);
const camera = new THREE.PerspectiveCamera(40, 900 / 600, 0.1, 100000);
camera.up.set(0, 0, 1);
scene.add(new THREE.AmbientLight(0xffffff, 0.6));
const sun = new THREE.DirectionalLight(0xffffff, 0.6); sun.position.set(1, -2, 3); scene.add(sun);
const part = new THREE.Group(); part.matrixAutoUpdate = false; scene.add(part);
const machine = new THREE.Group(); scene.add(machine);

// The path: printed moves as coloured segments, travels dashed, a swinging move through its samples.
const swingOf = new Map(D.swing.map(s => [s[0], s.slice(1)]));
const pr = [], prIndex = [], tr = [], prUpTo = [], trUpTo = [];
for (let i = 0; i < n; i++) {
  if (i > 0) {
    const pts = [tips[i - 1]], s = swingOf.get(i);
    if (s) for (let k = 0; k < s.length; k += 3) pts.push(new THREE.Vector3(s[k], s[k + 1], s[k + 2]));
    pts.push(tips[i]);
    for (let k = 1; k < pts.length; k++) {
      if (D.pose[i][7]) { pr.push(pts[k - 1], pts[k]); prIndex.push(i, i); } else tr.push(pts[k - 1], pts[k]);
    }
  }
  prUpTo.push(pr.length); trUpTo.push(tr.length);
}
const prGeo = new THREE.BufferGeometry().setFromPoints(pr);
const colours = new Float32Array(pr.length * 3);
prGeo.setAttribute('color', new THREE.BufferAttribute(colours, 3));
function recolour() {
  const c = new THREE.Color();
  for (let v = 0; v < pr.length; v++) { c.setHSL(0.6667 * (1 - fraction(D.pose[prIndex[v]])), 0.85, 0.45); colours.set([c.r, c.g, c.b], v * 3); }
  prGeo.attributes.color.needsUpdate = true;
  legend();
}
recolour();
const printed = new THREE.LineSegments(prGeo, new THREE.LineBasicMaterial({vertexColors: THREE.VertexColors}));
const travels = new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(tr),
                                       new THREE.LineDashedMaterial({color: 0x00897b, dashSize: size / 150, gapSize: size / 150}));
travels.computeLineDistances();
part.add(printed, travels);
summary.printed_segments = pr.length / 2; summary.travel_segments = tr.length / 2;
// The tool axis at up to 400 printed points.
const whisker = [], every = Math.max(1, Math.floor(n / 400));
for (let i = 0; i < n; i += every) {
  if (!D.pose[i][7] && framed !== tips) continue;
  const p = D.pose[i];
  whisker.push(tips[i], tips[i].clone().add(new THREE.Vector3(p[3], p[4], p[5]).multiplyScalar(0.06 * size)));
}
const axes = new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(whisker), new THREE.LineBasicMaterial({color: 0x555555}));
axes.visible = false; part.add(axes);
// Marks on the path.
const markDot = new THREE.SphereBufferGeometry(size / 120, 10, 8);
const allMarks = D.marks.concat(D.slowed);
for (const m of allMarks) {
  const s = new THREE.Mesh(markDot, new THREE.MeshBasicMaterial({color: KIND[m[0]].colour}));
  s.position.set(m[2], m[3], m[4]); part.add(s);
}
// Collisions at their contacts, red.
const hitDot = new THREE.SphereBufferGeometry(size / 200, 8, 6), hitMaterial = new THREE.MeshBasicMaterial({color: 0xff0000});
for (const c of D.collisions) { const s = new THREE.Mesh(hitDot, hitMaterial); s.position.set(...c.contact); part.add(s); }
// The bed's build volume (the linear joints' travel) and the axes, in the machine's base frame.
const lo = D.volume.lo.map((v, k) => D.volume.hi[k] > v ? v : box.min.getComponent(k));
const hi = D.volume.hi.map((v, k) => v > D.volume.lo[k] ? v : box.max.getComponent(k));
const vol = new THREE.Box3(new THREE.Vector3(lo[0], lo[1], Math.max(0, lo[2])), new THREE.Vector3(hi[0], hi[1], hi[2]));
const volume = new THREE.Box3Helper(vol, 0x9e9e9e); scene.add(volume);
scene.add(new THREE.AxesHelper(0.25 * size));
// The machine: each body posed by its chain frame. The machine file's own bodies (the collision
// check's) when it has them, every shape as the check takes it; else a default from the chains.
const bodies = [];
document.getElementById('bodies-source').textContent = D.own_bodies ? '(the machine file\u2019s own, as the collision check uses them)'
                                                                    : '(default, from the chains: the machine file has no [[bodies]])';
summary.body_source = D.own_bodies ? 'machine' : 'default';
summary.shapes = {}; summary.triangles = 0;
for (const b of D.bodies) {
  const partSide = b.frame.startsWith('part');
  const material = new THREE.MeshLambertMaterial({color: partSide ? 0xb0bec5 : 0x8d6e63, transparent: true, opacity: partSide ? 0.35 : 0.6,
                                                  side: THREE.DoubleSide});
  const [r, , len] = b.size;
  let obj;
  if (b.shape === 'box') obj = new THREE.Mesh(new THREE.BoxBufferGeometry(b.size[0], b.size[1], b.size[2]), material);
  // three.js builds these along y: turned onto z, as FCL's (a cone's apex at +length/2).
  else if (b.shape === 'cylinder') obj = new THREE.Mesh(new THREE.CylinderBufferGeometry(r, r, len, 24).rotateX(Math.PI / 2), material);
  else if (b.shape === 'cone') obj = new THREE.Mesh(new THREE.ConeBufferGeometry(r, len, 24).rotateX(Math.PI / 2), material);
  else if (b.shape === 'sphere') obj = new THREE.Mesh(new THREE.SphereBufferGeometry(r, 24, 16), material);
  else if (b.shape === 'capsule') {
    obj = new THREE.Group();
    obj.add(new THREE.Mesh(new THREE.CylinderBufferGeometry(r, r, len, 24, 1, true).rotateX(Math.PI / 2), material));
    for (const z of [-len / 2, len / 2]) { const s = new THREE.Mesh(new THREE.SphereBufferGeometry(r, 24, 12), material); s.position.set(0, 0, z); obj.add(s); }
  } else {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(b.vertices, 3));
    g.setIndex(b.triangles); g.computeVertexNormals();
    obj = new THREE.Mesh(g, material);
    summary.triangles += b.triangles.length / 3;
  }
  obj.matrixAutoUpdate = false; machine.add(obj);
  summary.shapes[b.shape] = (summary.shapes[b.shape] || 0) + 1;
  const a = b.pose, pose = new THREE.Matrix4().set(a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], 0, 0, 0, 1);
  bodies.push({b, mesh: obj, pose});
  const li = document.createElement('li'); li.setAttribute('data-body', b.shape);
  li.textContent = b.name + ': ' + b.shape + ' ' + b.size.map(v => +v.toFixed(2)).join(' \u00d7 ') +
                   (b.shape === 'mesh' ? ' (' + b.triangles.length / 3 + ' of ' + b.source_triangles + ' triangles drawn)' : '') + ' on frame ' + b.frame;
  document.getElementById('bodies').appendChild(li);
}
summary.bodies = bodies.length;

let controls = null;
if (renderer) {
  renderer.setSize(900, 600); holder.appendChild(renderer.domElement);
  controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.screenSpacePanning = true;
  controls.addEventListener('change', draw);
  summary.webgl = true;
} else {
  document.getElementById('nogl').textContent = 'WebGL is not available in this browser: the 3D view is not drawn (the lists and charts are).';
}
function draw() { if (renderer) renderer.render(scene, camera); }
function fit() {  // the printed part, as posed now, from above and in front
  const b = box.clone().applyMatrix4(part.matrix), c = b.getCenter(new THREE.Vector3());
  const r = Math.max(1, b.getSize(new THREE.Vector3()).length() / 2);
  camera.position.copy(c).add(new THREE.Vector3(0.9, -1.6, 1.1).normalize().multiplyScalar(r / Math.sin(camera.fov * Math.PI / 360)));
  camera.near = r / 100; camera.far = r * 100; camera.updateProjectionMatrix();
  if (controls) { controls.target.copy(c); controls.update(); }
  camera.lookAt(c); draw();
}
// The scrubber: the machine posed at a kept written move, its line and joints shown.
const scrub = document.getElementById('scrub'), upto = document.getElementById('upto');
scrub.max = Math.max(0, n - 1);
function pose(i) {
  i = Math.max(0, Math.min(n - 1, i)); scrub.value = i;
  if (!n) return;
  const q = D.q[i], F = {part: frames(D.chain.part, q), tool: frames(D.chain.tool, q)};
  part.matrix.copy(frameOf('part', F)); part.matrixWorldNeedsUpdate = true;
  for (const {b, mesh, pose} of bodies) { mesh.matrix.copy(frameOf(b.frame, F)).multiply(pose); mesh.matrixWorldNeedsUpdate = true; }
  const toPart = new THREE.Matrix4().getInverse(frameOf('part', F));
  const tip = new THREE.Vector3().applyMatrix4(frameOf('tool', F)).applyMatrix4(toPart);
  // Each body as posed: its frame in the base frame and in the part frame (rows of 3 x 4).
  const rows = m => { const e = m.elements; return [e[0], e[4], e[8], e[12], e[1], e[5], e[9], e[13], e[2], e[6], e[10], e[14]]; };
  summary.posed = bodies.map(({b, mesh}) => ({name: b.name, frame: b.frame, base: rows(mesh.matrix),
                                              part: rows(toPart.clone().multiply(mesh.matrix))}));
  printed.geometry.setDrawRange(0, upto.checked ? prUpTo[i] : Infinity);
  travels.geometry.setDrawRange(0, upto.checked ? trUpTo[i] : Infinity);
  document.getElementById('linetext').textContent = 'output line ' + D.line[i] + ' (written move ' + D.move[i] + '): ' + D.text[i];
  const t = document.getElementById('joints-now'); t.innerHTML = '';
  D.joints.forEach((j, k) => {
    const r = t.insertRow(); r.insertCell().textContent = j.name; r.insertCell().textContent = q[k].toFixed(3) + ' ' + j.unit;
    r.insertCell().textContent = j.min !== null ? '[' + j.min + ', ' + j.max + ']' : '';
  });
  const r = t.insertRow(); r.insertCell().textContent = 'tip'; r.insertCell().textContent = tip.toArray().map(v => v.toFixed(3)).join(', ');
  summary.scrubber = {index: i, line: D.line[i], move: D.move[i], joints: q, tip: tip.toArray(), text: D.text[i]};
  document.getElementById('summary').textContent = JSON.stringify(summary);
  draw();
}
function jump(move) {  // the last kept move at or before written move `move`
  let a = 0, b = n - 1;
  while (a < b) { const c = (a + b + 1) >> 1; if (D.move[c] <= move) a = c; else b = c - 1; }
  pose(a);
}
scrub.addEventListener('input', () => pose(Number(scrub.value)));
upto.addEventListener('change', () => pose(Number(scrub.value)));
document.getElementById('back').addEventListener('click', () => pose(Number(scrub.value) - 1));
document.getElementById('step').addEventListener('click', () => pose(Number(scrub.value) + 1));
let timer = null;
document.getElementById('play').addEventListener('click', e => {
  if (timer) { clearInterval(timer); timer = null; e.target.textContent = 'play'; return; }
  e.target.textContent = 'pause';
  timer = setInterval(() => { if (Number(scrub.value) >= n - 1) { clearInterval(timer); timer = null; e.target.textContent = 'play'; } else pose(Number(scrub.value) + Math.max(1, Math.round(n / 600))); }, 40);
});
mode.addEventListener('change', () => { recolour(); draw(); });
document.getElementById('axis').addEventListener('change', e => { axes.visible = e.target.checked; draw(); });
document.getElementById('machine').addEventListener('change', e => { machine.visible = e.target.checked; draw(); });
document.getElementById('fit').addEventListener('click', fit);
document.getElementById('worst').addEventListener('click', () => {  // the kept move standing for the largest deviation
  let w = 0; for (let i = 1; i < n; i++) if (D.pose[i][8] > D.pose[w][8]) w = i;
  pose(w);
});
// The lists: every kept mark, a button each that moves the scrubber to its written move.
function list(id, marks, attribute) {
  const ul = document.getElementById(id);
  for (const m of marks) {
    const li = document.createElement('li'); li.setAttribute(attribute, m[0]);
    const b = document.createElement('button'); b.textContent = 'move ' + m[5];
    b.addEventListener('click', () => jump(m[5]));
    li.appendChild(b); li.appendChild(document.createTextNode(' ' + KIND[m[0]].text + ' (tip ' + m.slice(2, 5).map(v => v.toFixed(2)).join(', ') + ')'));
    ul.appendChild(li);
    summary.listed[m[0]] = (summary.listed[m[0]] || 0) + 1;
  }
}
list('marks', D.marks, 'data-kind');
// The collisions, each with the bodies that met, clickable to its written move; the re-routed
// travels the same way, clickable to the detour's crossing (its written move after the lift).
// Each list says when it holds only the first of its count.
function bodyList(id, items, attribute, count, text) {
  for (const c of items) {
    const li = document.createElement('li'); li.setAttribute(attribute, c.tool);
    const b = document.createElement('button'); b.textContent = 'move ' + c.move;
    b.addEventListener('click', () => jump(c.move));
    li.appendChild(b);
    li.appendChild(document.createTextNode(' input line ' + c.line + ': ' + text(c)));
    document.getElementById(id).appendChild(li);
  }
  if (count > items.length) {
    const li = document.createElement('li'); li.textContent = '\u2026 the first ' + items.length + ' of ' + count + ' listed';
    document.getElementById(id).appendChild(li);
  }
}
const metWhat = c => c.other === null ? 'the printed part (line ' + c.bead_line + ')' : c.other;
bodyList('collisions', D.collisions, 'data-collision', D.counts.collisions,
         c => c.tool + ' meets ' + metWhat(c) + ' at ' + c.contact.map(v => v.toFixed(2)).join(', '));
summary.listed.collision = D.collisions.length;
summary.marks.collision = D.counts.collisions;
bodyList('reroutes', D.reroutes, 'data-reroute', D.counts.reroutes, c => 'lifted, ' + c.tool + ' would meet ' + metWhat(c));
summary.listed.reroute = D.reroutes.length;
summary.marks.reroute = D.counts.reroutes;
list('slowed', D.slowed, 'data-feed');
for (const [first, last] of D.drains) {  // output line ranges: to the last kept move at or before the first line
  const li = document.createElement('li'), b = document.createElement('button');
  b.textContent = 'lines ' + first + '\u2013' + last; li.setAttribute('data-link', 'drain');
  b.addEventListener('click', () => { let i = 0; while (i + 1 < n && D.line[i + 1] <= first) i++; pose(i); });
  li.appendChild(b); document.getElementById('drains').appendChild(li);
}
summary.listed.drains = D.drains.length;
for (const k of ['pole', 'unwind', 'branch', 'rezero', 'slowed']) summary.marks[k] = D.counts[k];
summary.counts = D.counts;
// The joints over the file against their limits, the marks as vertical lines.
const panel = document.getElementById('joints');
D.joints.forEach((j, k) => {
  const c = document.createElement('canvas'); c.width = 900; c.height = 90; panel.appendChild(c);
  const h = c.getContext('2d');
  const vals = D.q.map(r => r[k]);
  let a = Math.min(...vals), b = Math.max(...vals);
  if (j.min !== null) a = Math.min(a, j.min);
  if (j.max !== null) b = Math.max(b, j.max);
  if (!(b > a)) { a -= 1; b += 1; }
  const Y = v => 80 - (v - a) / (b - a) * 70, X = i => 60 + i / Math.max(1, n - 1) * 830;
  h.fillStyle = '#fff'; h.fillRect(0, 0, c.width, c.height);
  h.strokeStyle = 'red'; h.setLineDash([5, 4]);
  for (const lim of [j.min, j.max]) if (lim !== null) { h.beginPath(); h.moveTo(60, Y(lim)); h.lineTo(890, Y(lim)); h.stroke(); }
  h.setLineDash([]); h.strokeStyle = 'steelblue'; h.beginPath();
  vals.forEach((v, i) => { if (i) h.lineTo(X(i), Y(v)); else h.moveTo(X(i), Y(v)); }); h.stroke();
  h.fillStyle = '#000'; h.font = '12px sans-serif';
  h.fillText(j.name + ' ' + j.unit, 4, 14);
  h.fillText(j.low + ' \u2026 ' + j.high, 4, 86);
  for (const m of D.marks) {
    const x = 60 + m[1] * 830;
    h.strokeStyle = KIND[m[0]].colour; h.beginPath(); h.moveTo(x, 10); h.lineTo(x, 80); h.stroke();
  }
  h.strokeStyle = '#f00'; h.lineWidth = 2;
  for (const c of D.collisions) { const x = 60 + c.at * 830; h.beginPath(); h.moveTo(x, 2); h.lineTo(x, 10); h.stroke(); }  // a tick above: many may crowd
  h.lineWidth = 1;
  c.addEventListener('click', e => pose(Math.round((e.offsetX - 60) / 830 * (n - 1))));
});
pose(0);
fit();
const at = hash.get('line');
if (at !== null) { let i = 0; while (i + 1 < n && D.line[i + 1] <= Number(at)) i++; pose(i); }
// #collision=K: as a click on the K-th listed collision.
const hit = hash.get('collision'), hits = document.querySelectorAll('#collisions li[data-collision] button');
if (hit !== null && hits[Number(hit)]) hits[Number(hit)].click();
document.title = document.title + ' (drawn)';
)JS";


// The kept moves: joints as written, and each one's pose, tilt, extrusion, deviation and feed;
// then their move and line numbers, texts, and the swings drawn as sampled.
std::string kept_json(const Kinematics& kin, const KeptMoves& kept, double tolerance) {
    const std::size_t n = kept.size(), joints = kept.joints;
    std::string data = "{\"q\": [";
    std::string pose = "\"pose\": [";
    double max_tilt = 0, max_feed = 0;
    std::vector<double> q(joints);
    for (std::size_t i = 0; i < n; ++i) {
        std::copy_n(kept.q.begin() + std::ptrdiff_t(i * joints), joints, q.begin());
        data += i ? ",[" : "[";
        for (std::size_t j = 0; j < joints; ++j) {
            if (j) data += ',';
            data += joint_num(q[j]);
        }
        data += "]";
        const Pose p = kin.forward(q);
        const double tilt = std::acos(std::clamp(p.axis.z(), -1.0, 1.0)) * 180.0 / M_PI;
        max_tilt = std::max(max_tilt, tilt);
        max_feed = std::max(max_feed, kept.feed[i]);
        pose += std::string(i ? "," : "") + "[" + num(p.tip.x()) + "," + num(p.tip.y()) + "," + num(p.tip.z()) + "," + num(p.axis.x()) + "," +
                num(p.axis.y()) + "," + num(p.axis.z()) + "," + num(tilt) + "," + (kept.prints[i] ? "1" : "0") + "," + num(kept.dev[i]) + "," +
                num(kept.feed[i]) + "]";
    }
    data += "], " + pose + "], \"max_tilt\": " + num(max_tilt) + ", \"max_feed\": " + num(max_feed) + ", \"tolerance\": " + num(tolerance);
    data += ", \"move\": [";
    for (std::size_t i = 0; i < n; ++i) data += (i ? "," : "") + std::to_string(kept.move_no[i]);
    data += "], \"line\": [";
    for (std::size_t i = 0; i < n; ++i) data += (i ? "," : "") + std::to_string(kept.line_no[i]);
    data += "], \"text\": [";
    for (std::size_t i = 0; i < n; ++i) data += (i ? "," : "") + json_text(kept.text[i]);
    data += "], \"swing\": [";
    bool first = true;
    for (std::size_t i = 0; i < n; ++i) {
        if (kept.swing[i].empty()) continue;
        data += std::string(first ? "" : ",") + "[" + std::to_string(i);
        for (double v : kept.swing[i]) data += "," + num(v);
        data += "]";
        first = false;
    }
    return data + "]";
}

// Where a written move sits along the joint charts, which draw the kept moves (every
// `every`-th written move from the first) evenly: between the kept ones around it.
double chart_at(std::uint64_t move, const KeptMoves& kept) {
    const std::size_t n = kept.size();
    return n > 1 ? std::min(1.0, double(move) / double(kept.every) / double(n - 1)) : 0.0;
}

std::string mark_list(const std::vector<PreviewMark>& list, const KeptMoves& kept) {
    std::string o;
    for (std::size_t i = 0; i < list.size(); ++i) {
        const PreviewMark& k = list[i];
        o += std::string(i ? "," : "") + "[\"" + kind_name(k.kind) + "\"," + num(chart_at(k.move, kept)) + "," + num(k.tip[0]) + "," +
             num(k.tip[1]) + "," + num(k.tip[2]) + "," + std::to_string(k.move) + "]";
    }
    return o;
}

std::string joints_json(const Machine& m, const PreviewData& d) {
    std::string data;
    for (std::size_t j = 0; j < m.joints.size(); ++j) {
        const auto& J = m.joints[j];
        data += std::string(j ? "," : "") + "{\"name\": \"" + J.output + "\", \"input\": \"" + J.name + "\", \"unit\": \"" + (J.rotary ? "deg" : "mm") +
                "\", \"min\": " + (J.min > -1e299 ? num(J.min) : "null") + ", \"max\": " + (J.max < 1e299 ? num(J.max) : "null") +
                ", \"low\": " + joint_num(d.low[j]) + ", \"high\": " + joint_num(d.high[j]) + ", \"max_feed\": " + num(J.max_feed) + "}";
    }
    return data;
}

// The machine's own bodies, else the default from the chains: "own_bodies" and "bodies".
std::string bodies_json(const Machine& m) {
    std::vector<PreviewBody> bodies = machine_bodies(m);
    const bool own = !bodies.empty();
    if (!own) bodies = default_bodies(m);
    std::string data = ", \"own_bodies\": " + std::string(own ? "true" : "false") + ", \"bodies\": [";
    for (std::size_t i = 0; i < bodies.size(); ++i) {
        const auto& b = bodies[i];
        data += std::string(i ? "," : "") + "{\"name\": " + json_text(b.name) + ", \"frame\": \"" + b.frame + "\", \"shape\": \"" +
                shape_name(b.shape) + "\", \"size\": [" + num(b.size[0]) + "," + num(b.size[1]) + "," + num(b.size[2]) + "], \"pose\": [";
        for (std::size_t k = 0; k < 12; ++k) data += (k ? "," : "") + num(b.pose[k]);
        data += "]";
        if (b.shape == PreviewBody::Shape::Mesh) {
            data += ", \"source_triangles\": " + std::to_string(b.source_triangles) + ", \"vertices\": [";
            for (std::size_t k = 0; k < b.vertices.size(); ++k) data += (k ? "," : "") + num(b.vertices[k]);
            data += "], \"triangles\": [";
            for (std::size_t k = 0; k < b.triangles.size(); ++k) data += (k ? "," : "") + std::to_string(b.triangles[k]);
            data += "]";
        }
        data += "}";
    }
    return data + "]";
}

// The collisions the check found (--collision warn), each on the written move of its piece; the
// re-routed travels, each on its crossing: the detour's second written move (the lift first, the
// descent onto the travel's end after).
std::string collisions_json(const CollisionLog& log, const PreviewData& d) {
    const std::uint64_t last = d.moves > 0 ? d.moves - 1 : 0;
    std::string data = "\"collisions\": [";
    const auto& hits = log.collisions().marks;
    for (std::size_t i = 0; i < hits.size(); ++i) {
        const auto& c = hits[i];
        const std::uint64_t move = std::min<std::uint64_t>(c.move, last);
        data += std::string(i ? "," : "") + "{\"move\": " + std::to_string(move) + ", \"at\": " + num(chart_at(move, d.kept)) + ", \"line\": " +
                std::to_string(c.line) + ", \"tool\": " + json_text(c.tool) + ", \"other\": " +
                (c.other.empty() ? std::string("null") : json_text(c.other)) + ", \"bead_line\": " + std::to_string(c.bead_line) +
                ", \"contact\": [" + num(c.at[0]) + "," + num(c.at[1]) + "," + num(c.at[2]) + "]}";
    }
    data += "], \"reroutes\": [";
    const auto& lifts = log.reroutes().marks;
    for (std::size_t i = 0; i < lifts.size(); ++i) {
        const auto& c = lifts[i];
        const std::uint64_t move = std::min<std::uint64_t>(c.move + 1, last);
        data += std::string(i ? "," : "") + "{\"move\": " + std::to_string(move) + ", \"line\": " + std::to_string(c.line) +
                ", \"tool\": " + json_text(c.tool) + ", \"other\": " + (c.other.empty() ? std::string("null") : json_text(c.other)) +
                ", \"bead_line\": " + std::to_string(c.bead_line) + "}";
    }
    return data + "]";
}

std::string counts_json(const DeviationReport& r, const PreviewData& d) {
    const EventLog& e = r.events;
    return ", \"counts\": {\"moves_written\": " + std::to_string(d.moves) + ", \"output_moves\": " + std::to_string(r.stats.pieces) +
           ", \"pole\": " + std::to_string(e.pole_crossings()) + ", \"unwind\": " + std::to_string(e.unwinds()) +
           ", \"branch\": " + std::to_string(e.branch_changes()) + ", \"rezero\": " + std::to_string(e.rezeros()) +
           ", \"slowed\": " + std::to_string(d.slowed) + ", \"slowed_runs\": " + std::to_string(d.slowed_runs) +
           ", \"collisions\": " + std::to_string(r.collisions.collisions().count) + ", \"reroutes\": " + std::to_string(r.collisions.reroutes().count) +
           "}";
}

// The counts above the view, as a sentence.
std::string counts_text(const DeviationReport& r, const PreviewData& d, std::size_t marked) {
    const EventLog& e = r.events;
    const std::uint64_t total = e.pole_crossings() + e.unwinds() + e.branch_changes() + e.rezeros();
    const std::uint64_t passed = d.moves >= r.stats.pieces ? d.moves - r.stats.pieces : 0;
    const std::uint64_t collisions = r.collisions.collisions().count;
    return std::to_string(d.moves) + " moves written, " + std::to_string(d.kept.size()) + " shown (" + std::to_string(r.stats.pieces) +
           " translated moves, as the report's output_moves; " + std::to_string(passed) +
           " passed on as written: joint moves before the tip is placed). " + std::to_string(e.pole_crossings()) + " pole crossings, " +
           std::to_string(e.unwinds()) + " unwinds, " + std::to_string(e.branch_changes()) + " branch changes, " + std::to_string(e.rezeros()) +
           " re-zeros marked" + (total > marked ? " (the first " + std::to_string(marked) + " of " + std::to_string(total) + ")" : "") + "; " +
           std::to_string(d.slowed) + " moves at a joint's max_feed (" + std::to_string(d.slowed_runs) + " runs marked)" +
           (collisions > 0 ? "; " + std::to_string(collisions) + " collisions found (--collision warn)" : "") + ".";
}

}  // namespace

std::string preview_page(const Kinematics& kin, const DeviationReport& report, const PreviewData& d, const std::vector<PreviewMark>& marks,
                         const std::string& title) {
    const Machine& m = kin.machine();
    std::string data = kept_json(kin, d.kept, m.motion.tolerance);
    data += ", \"marks\": [" + mark_list(marks, d.kept) + "], \"joints\": [" + joints_json(m, d) + "], \"slowed\": [" +
            mark_list(d.slowed_marks, d.kept) + "], \"drains\": [";
    for (std::size_t i = 0; i < d.drains.size(); ++i)
        data += std::string(i ? "," : "") + "[" + std::to_string(d.drains[i].first) + "," + std::to_string(d.drains[i].second) + "]";
    data += "]";
    data += ", \"chain\": {\"part\": " + chain_json(m.part_chain) + ", \"tool\": " + chain_json(m.tool_chain) + "}";
    data += bodies_json(m) + ", " + collisions_json(report.collisions, d);
    const BuildVolume v = build_volume(m);
    data += ", \"volume\": {\"lo\": [" + num(v.lo[0]) + "," + num(v.lo[1]) + "," + num(v.lo[2]) + "], \"hi\": [" + num(v.hi[0]) + "," +
            num(v.hi[1]) + "," + num(v.hi[2]) + "]}";
    data += counts_json(report, d);
    data += ", \"three\": \"" + std::string(three_js::kRevision) + "\"}";
    return "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>xlate5 preview: " + html_text(title) + "</title>\n<style>" + kStyle +
           "</style></head>\n<body>\n<h3>" + html_text(title) + "</h3>\n<p id=\"counts\">" + counts_text(report, d, marks.size()) + "</p>\n" +
           kBody + "<script type=\"application/json\" id=\"data\">" + data + "</script>\n<script>/* three.js r" + three_js::kRevision +
           " (MIT licence, Debian's libjs-three) */\n" + three_js::kSource + "\n</script>\n<script>\n" + three_js::kOrbitControls +
           "\n</script>\n<script>" + kScript + "</script>\n</body></html>\n";
}

}  // namespace xlate5
