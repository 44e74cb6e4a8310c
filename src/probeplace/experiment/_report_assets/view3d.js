// report.html's 3D views (experiment/_report_html.py): one per scene, no server, no network.
//
// three.js sits in the page as inert text (<script type="text/plain" id="three-js">): a page opened from
// file:// may not import a module file beside it, but it may import a blob it made itself.
// Each <section class="view3d"> holds its data as JSON: gzipped, base64 typed arrays of the scene's
// triangles, a colour palette, the evaluation's camera and the probe sets of the representative runs.
//
// Test hook: window.probeplaceViews, one entry per drawn view: {scene, ready (after the first frame),
// set (index shown), show(i), colour() -> [r, g, b] of the shown set, project() -> canvas CSS pixel
// positions {x, y, inside} of the shown probes}.

window.probeplaceViews = [];

const src = document.getElementById("three-js").textContent;
const THREE = await import(URL.createObjectURL(new Blob([src], { type: "text/javascript" })));
// Colours are shown as given (sRGB bytes in, the same bytes out): no linear-light conversion anywhere.
THREE.ColorManagement.enabled = false;

async function inflate(b64) {
  const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
  return new Response(stream).arrayBuffer();
}

// Non-indexed triangles with one colour per face, shaded once by a fixed light: the walls of a box stand
// apart without a lighting model (and the probes' unlit colour stays exact).
async function sceneMesh(d) {
  const V = new Float32Array(await inflate(d.vertices));
  const F = new Uint32Array(await inflate(d.faces));
  const raw = await inflate(d.colour_index);
  const C = d.index_bytes === 1 ? new Uint8Array(raw) : new Uint16Array(raw);
  const nf = F.length / 3;
  const pos = new Float32Array(nf * 9);
  const col = new Uint8Array(nf * 9);
  const L = new THREE.Vector3(0.35, 0.85, 0.4).normalize();
  const a = new THREE.Vector3(), b = new THREE.Vector3(), c = new THREE.Vector3();
  for (let f = 0; f < nf; f++) {
    a.fromArray(V, 3 * F[3 * f]);
    b.fromArray(V, 3 * F[3 * f + 1]);
    c.fromArray(V, 3 * F[3 * f + 2]);
    a.toArray(pos, 9 * f);
    b.toArray(pos, 9 * f + 3);
    c.toArray(pos, 9 * f + 6);
    const n = c.sub(b).cross(b.sub(a).negate()).normalize(); // (c − b) × (a − b): the face normal
    const shade = 0.5 + 0.5 * Math.abs(n.dot(L) || 0);
    const rgb = d.palette[C[f]];
    for (let k = 0; k < 3; k++) for (let ch = 0; ch < 3; ch++) col[9 * f + 3 * k + ch] = rgb[ch] * shade;
  }
  const geom = new THREE.BufferGeometry();
  geom.setAttribute("position", new THREE.BufferAttribute(pos, 3));
  geom.setAttribute("color", new THREE.BufferAttribute(col, 3, true));
  geom.computeBoundingSphere();
  return new THREE.Mesh(geom, new THREE.MeshBasicMaterial({ vertexColors: true, side: THREE.DoubleSide }));
}

// A probe set: round points with a black rim (it shows on walls of a similar colour), their size falling
// with distance like a sphere's but held between MIN_PX and MAX_PX, so a probe next to the camera does
// not fill the view and a far one stays visible.
const MIN_PX = 9, MAX_PX = 22;
const PROBE_VERT = `
uniform float scale, minPx, maxPx;
void main() {
  vec4 mv = modelViewMatrix * vec4(position, 1.0);
  gl_Position = projectionMatrix * mv;
  gl_PointSize = clamp(scale / -mv.z, minPx, maxPx);
}`;
const PROBE_FRAG = `
uniform vec3 colour;
void main() {
  float r = length(2.0 * gl_PointCoord - 1.0);
  if (r > 1.0) discard;
  gl_FragColor = vec4(r > 0.7 ? vec3(0.0) : colour, 1.0);
}`;

function probePoints(set, radius, throughWalls, pixelRatio) {
  const geom = new THREE.BufferGeometry();
  geom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(set.pos.flat()), 3));
  const mat = new THREE.ShaderMaterial({
    uniforms: {
      colour: { value: new THREE.Color(set.colour) },
      scale: { value: 0 }, // set per frame: the diameter in pixels at unit distance
      minPx: { value: MIN_PX * pixelRatio },
      maxPx: { value: MAX_PX * pixelRatio },
    },
    vertexShader: PROBE_VERT,
    fragmentShader: PROBE_FRAG,
    depthTest: !throughWalls,
    depthWrite: !throughWalls,
  });
  const points = new THREE.Points(geom, mat);
  points.renderOrder = 1;
  points.frustumCulled = false;
  points.userData.radius = radius;
  return points;
}

// Orbit about a target: drag turns about the camera's up axis and its right axis, shift- or right-drag
// pans, the wheel dollies; double-click returns to the evaluation's camera.
function orbit(canvas, camera, start, redraw) {
  const target = new THREE.Vector3();
  const up = new THREE.Vector3();
  const reset = () => {
    camera.position.fromArray(start.position);
    target.fromArray(start.look_at);
    up.fromArray(start.up).normalize();
    camera.up.copy(up);
    camera.lookAt(target);
    redraw();
  };
  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => {
    drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button !== 0 };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener("pointerup", () => (drag = null));
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    const offset = camera.position.clone().sub(target);
    const right = new THREE.Vector3().crossVectors(offset, up).normalize();
    if (drag.pan) {
      const h = 2 * offset.length() * Math.tan(THREE.MathUtils.degToRad(camera.fov / 2));
      const camUp = new THREE.Vector3().crossVectors(right, offset).normalize();
      const move = right.multiplyScalar((dx * h) / canvas.clientHeight).add(camUp.multiplyScalar((dy * h) / canvas.clientHeight));
      target.add(move);
      camera.position.add(move);
    } else {
      offset.applyAxisAngle(up, (-2 * Math.PI * dx) / canvas.clientWidth);
      const tilted = offset.clone().applyAxisAngle(right, (-Math.PI * dy) / canvas.clientHeight);
      const angle = tilted.angleTo(up); // stop short of the poles: the view would flip over
      if (angle > 0.05 && angle < Math.PI - 0.05) offset.copy(tilted);
      camera.position.copy(target).add(offset);
    }
    camera.lookAt(target);
    redraw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const offset = camera.position.clone().sub(target).multiplyScalar(Math.exp(e.deltaY * 0.001));
    camera.position.copy(target).add(offset);
    redraw();
  }, { passive: false });
  canvas.addEventListener("dblclick", reset);
  reset();
}

async function setUp(section) {
  const d = JSON.parse(section.querySelector(".view-data").textContent);
  const canvas = section.querySelector("canvas");
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
  renderer.setPixelRatio(window.devicePixelRatio);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color("#1d1f24");
  scene.add(await sceneMesh(d));
  const diag = 2 * scene.children[0].geometry.boundingSphere.radius;
  const camera = new THREE.PerspectiveCamera(d.camera.fov_y_deg, 1, diag * 1e-3, diag * 20);
  const view = { scene: d.scene, ready: false, set: 0, throughWalls: true };
  let probes = null;
  let pending = false;
  const draw = () => {
    const w = canvas.clientWidth, h = canvas.clientHeight;
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    const perUnit = (h * renderer.getPixelRatio()) / (2 * Math.tan(THREE.MathUtils.degToRad(camera.fov / 2)));
    if (probes) probes.material.uniforms.scale.value = 2 * probes.userData.radius * perUnit;
    renderer.render(scene, camera);
  };
  const redraw = () => {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      draw();
    });
  };
  const toolbar = section.querySelector(".toolbar");
  const buttons = d.sets.map((s, i) => {
    const b = document.createElement("button");
    b.innerHTML = `<span class="swatch" style="background:${s.colour}"></span>`;
    b.append(s.name);
    b.title = s.run;
    b.addEventListener("click", () => view.show(i));
    toolbar.append(b);
    return b;
  });
  const walls = document.createElement("label");
  walls.innerHTML = '<input type="checkbox" checked> probes through walls';
  walls.querySelector("input").addEventListener("change", (e) => {
    view.throughWalls = e.target.checked;
    view.show(view.set);
  });
  toolbar.append(walls);
  view.show = (i) => {
    if (probes) scene.remove(probes);
    view.set = i;
    probes = d.sets.length ? probePoints(d.sets[i], d.radius, view.throughWalls, renderer.getPixelRatio()) : null;
    if (probes) scene.add(probes);
    buttons.forEach((b, k) => b.classList.toggle("on", k === i));
    redraw();
  };
  view.colour = () => new THREE.Color(d.sets[view.set].colour).toArray().map((x) => Math.round(255 * x));
  view.project = () =>
    (d.sets[view.set]?.pos ?? []).map((p) => {
      const v = new THREE.Vector3(p[0], p[1], p[2]).project(camera);
      const inside = Math.abs(v.x) <= 1 && Math.abs(v.y) <= 1 && Math.abs(v.z) <= 1;
      return { x: ((v.x + 1) / 2) * canvas.clientWidth, y: ((1 - v.y) / 2) * canvas.clientHeight, inside };
    });
  view.show(0);
  orbit(canvas, camera, d.camera, redraw);
  new ResizeObserver(redraw).observe(canvas);
  draw();
  // ready once the first frame has reached the screen (the frame after the one that drew it)
  requestAnimationFrame(() => requestAnimationFrame(() => (view.ready = true)));
  window.probeplaceViews.push(view);
}

for (const section of document.querySelectorAll("section.view3d")) {
  if (!section.querySelector(".view-data")) continue;
  try {
    await setUp(section);
  } catch (err) {
    // no WebGL, no DecompressionStream: the rest of the report still reads; say why in the view's place
    const why = document.createElement("p");
    why.className = "why";
    why.textContent = `3D view unavailable in this browser: ${err.message}`;
    section.querySelector("canvas").replaceWith(why);
    console.warn(err);
  }
}
