// The report's interactive viewers, bundled with three.js into ../static/viewers.min.js
// (`npm ci && npm run build` in this folder). The report embeds each viewer's data as a
// JSON <script> (binary arrays base64-encoded) next to a <div class="viewer">; mountAll()
// builds every viewer on the page. Kinds:
//   "prt":     a DeepPRT test frame as a mesh with per-vertex SH transfer per model; the page
//              shades 1/pi sum_j l_j t_j for a chosen probe turned about +y, or the error
//              against the ground truth; views side by side with one orbiting camera.
//   "meshes":  textured glTF meshes side by side (reference, QEM, bake, ours) with one
//              orbiting camera and a directional light the sliders move.
//   "frames":  image sequences side by side with a scrubber (metaballs demo, NDR relit by
//              turns of its map), optionally with an overlay toggle.
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";

function decode(b64, Type) {
  const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  return Type === Uint8Array ? bytes : new Type(bytes.buffer);
}

function element(tag, attrs = {}, parent = null) {
  const el = document.createElement(tag);
  Object.entries(attrs).forEach(([k, v]) => (k === "text" ? (el.textContent = v) : el.setAttribute(k, v)));
  if (parent) parent.appendChild(el);
  return el;
}

// A labelled range input; `show(value)` (optional) gives the text shown beside it.
function slider(parent, label, min, max, step, value, onInput, show = null) {
  const wrap = element("label", { class: "control" }, parent);
  wrap.append(`${label} `);
  const input = element("input", { type: "range", min, max, step, value }, wrap);
  const readout = show ? element("span", { class: "readout", text: ` ${show(value)}` }, wrap) : null;
  input.addEventListener("input", () => {
    const v = Number(input.value);
    if (readout) readout.textContent = ` ${show(v)}`;
    onInput(v);
  });
  return input;
}

function select(parent, label, options, onChange) {
  const wrap = element("label", { class: "control" }, parent);
  wrap.append(`${label} `);
  const sel = element("select", {}, wrap);
  options.forEach((o) => element("option", { value: o, text: o }, sel));
  sel.addEventListener("change", () => onChange(sel.value));
  return sel;
}

// Side-by-side views of one scene each, rendered into one canvas with scissor rectangles
// and one camera that OrbitControls moves.
class SideBySide {
  constructor(root, labels, aspect = 1.0) {
    this.labels = labels;
    this.canvas = element("canvas", { class: "viewer-canvas" }, root);
    const width = Math.min(root.clientWidth || 900, 1000);
    this.size = [width, Math.round((width / labels.length) * aspect) + 24];
    this.renderer = new THREE.WebGLRenderer({ canvas: this.canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(1);
    this.renderer.setSize(...this.size);
    this.renderer.setScissorTest(true);
    this.camera = new THREE.PerspectiveCamera(35, width / labels.length / (this.size[1] - 24), 0.01, 100);
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.addEventListener("change", () => this.render());
    this.scenes = labels.map(() => new THREE.Scene());
    const captions = element("div", { class: "viewer-captions" }, root);
    this.captions = labels.map((l) => element("span", { text: l, style: `width:${100 / labels.length}%` }, captions));
  }
  frame(object) {
    const box = new THREE.Box3().setFromObject(object);
    const centre = box.getCenter(new THREE.Vector3());
    const radius = box.getSize(new THREE.Vector3()).length() / 2;
    this.camera.position.copy(centre).add(new THREE.Vector3(0.35, 0.45, 1.0).normalize().multiplyScalar(radius * 3.2));
    this.camera.near = radius / 50;
    this.camera.far = radius * 20;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(centre);
    this.controls.update();
  }
  render() {
    const [w, h] = this.size;
    const cell = w / this.scenes.length;
    this.scenes.forEach((scene, i) => {
      this.renderer.setViewport(i * cell, 0, cell, h - 24);
      this.renderer.setScissor(i * cell, 0, cell, h - 24);
      this.renderer.setClearColor(0xf4f4f4);
      this.renderer.render(scene, this.camera);
    });
  }
}

function mountPrt(root, data) {
  const models = Object.keys(data.transfer);
  const positions = decode(data.positions, Float32Array);
  const indices = decode(data.indices, Uint32Array);
  const transfer = Object.fromEntries(models.map((m) => [m, decode(data.transfer[m], Float32Array)]));
  const probes = Object.fromEntries(
    Object.entries(data.probes).map(([name, p]) => [name, { turns: p.turns, lights: decode(p.lights, Float32Array) }])
  );
  const k = data.coefficients;
  const vertices = positions.length / 3;
  const gt = transfer[models[0]];
  const state = { probe: Object.keys(probes)[0], turn: 0, mode: "shaded" };
  const controls = element("div", { class: "viewer-controls" }, root);
  const view = new SideBySide(root, models);
  const meshes = models.map((m, i) => {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(positions, 3));
    geometry.setAttribute("color", new THREE.BufferAttribute(new Float32Array(vertices * 3), 3));
    geometry.setIndex(new THREE.BufferAttribute(indices, 1));
    const mesh = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({ vertexColors: true, side: THREE.DoubleSide }));
    view.scenes[i].add(mesh);
    return mesh;
  });
  view.frame(meshes[0]);
  const radiance = (t, light, v) => {
    const out = [0, 0, 0];
    for (let c = 0; c < 3; c++) {
      let s = 0;
      for (let j = 0; j < k; j++) s += light[(j * 3) + c] * t[v * k + j];
      out[c] = Math.max(s, 0) / Math.PI;
    }
    return out;
  };
  // One exposure for every probe and turn (the brightest ground-truth vertex of any), so
  // turning the light or changing the probe shows its real change in brightness.
  let peak = 1e-9;
  Object.values(probes).forEach((p) => {
    for (let t = 0; t < p.turns.length; t++) {
      const light = p.lights.subarray(t * k * 3, (t + 1) * k * 3);
      for (let v = 0; v < vertices; v++) peak = Math.max(peak, ...radiance(gt, light, v));
    }
  });
  const update = () => {
    const p = probes[state.probe];
    const light = p.lights.subarray(state.turn * k * 3, (state.turn + 1) * k * 3);
    models.forEach((m, i) => {
      const colours = meshes[i].geometry.attributes.color;
      for (let v = 0; v < vertices; v++) {
        const value = radiance(transfer[m], light, v);
        if (state.mode === "shaded") {
          value.forEach((x, c) => colours.array[v * 3 + c] = Math.pow(Math.min(x / peak, 1), 1 / 2.2));
        } else {
          const truth = radiance(gt, light, v);
          const err = Math.min((Math.abs(value[0] - truth[0]) + Math.abs(value[1] - truth[1]) + Math.abs(value[2] - truth[2])) / 3 / peak * 10, 1);
          colours.array[v * 3] = err;
          colours.array[v * 3 + 1] = 0.2 * (1 - err);
          colours.array[v * 3 + 2] = 1 - err;
        }
      }
      colours.needsUpdate = true;
    });
    view.render();
  };
  select(controls, "probe", Object.keys(probes), (v) => { state.probe = v; update(); });
  slider(controls, "turn the probe about +y", 0, probes[state.probe].turns.length - 1, 1, 0, (v) => { state.turn = v; update(); },
    (v) => `${Math.round(probes[state.probe].turns[v])} deg`);
  select(controls, "show", ["shaded", "error x10 vs ground truth"], (v) => { state.mode = v === "shaded" ? "shaded" : "error"; update(); });
  update();
  return view;
}

function mountMeshes(root, data) {
  const names = Object.keys(data.meshes);
  const controls = element("div", { class: "viewer-controls" }, root);
  const view = new SideBySide(root, names.map((n) => `${n}: ${data.captions[n] || ""}`));
  const lights = view.scenes.map((scene) => {
    scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 0.6));
    const light = new THREE.DirectionalLight(0xffffff, 2.5);
    scene.add(light);
    scene.add(light.target);
    return light;
  });
  const state = { azimuth: 30, elevation: 35 };
  const placeLights = () => {
    const a = THREE.MathUtils.degToRad(state.azimuth);
    const e = THREE.MathUtils.degToRad(state.elevation);
    lights.forEach((l) => l.position.set(Math.sin(a) * Math.cos(e), Math.sin(e), Math.cos(a) * Math.cos(e)).multiplyScalar(10));
    view.render();
  };
  const loader = new GLTFLoader();
  let framed = false;
  return Promise.all(
    names.map((name, i) =>
      loader.parseAsync(decode(data.meshes[name], Uint8Array).buffer, "").then((gltf) => {
        view.scenes[i].add(gltf.scene);
        if (!framed) { view.frame(gltf.scene); framed = true; }
      })
    )
  ).then(() => {
    slider(controls, "light azimuth", -180, 180, 1, state.azimuth, (v) => { state.azimuth = v; placeLights(); });
    slider(controls, "light elevation", -10, 89, 1, state.elevation, (v) => { state.elevation = v; placeLights(); });
    placeLights();
    return view;
  });
}

function mountFrames(root, data) {
  const names = Object.keys(data.frames);
  const count = data.frames[names[0]].length;
  const controls = element("div", { class: "viewer-controls" }, root);
  const row = element("div", { class: "viewer-row" }, root);
  const panels = names.map((name) => {
    const cell = element("figure", { class: "viewer-cell" }, row);
    const canvas = element("canvas", { class: "viewer-canvas" }, cell);
    element("figcaption", { text: name }, cell);
    return canvas;
  });
  const images = names.map((n) => data.frames[n].map((b64) => { const im = new Image(); im.src = `data:image/png;base64,${b64}`; return im; }));
  const overlays = data.overlay ? names.map((n) => (data.overlay[n] || []).map((b64) => { const im = new Image(); im.src = `data:image/png;base64,${b64}`; return im; })) : null;
  const state = { index: 0, overlay: false };
  const draw = () => {
    panels.forEach((canvas, i) => {
      const image = images[i][state.index];
      canvas.width = image.naturalWidth * data.scale;
      canvas.height = image.naturalHeight * data.scale;
      const ctx = canvas.getContext("2d");
      ctx.imageSmoothingEnabled = false;
      ctx.drawImage(image, 0, 0, canvas.width, canvas.height);
      const over = overlays && overlays[i][state.index];
      if (state.overlay && over) { ctx.globalAlpha = 0.6; ctx.drawImage(over, 0, 0, canvas.width, canvas.height); ctx.globalAlpha = 1; }
    });
  };
  slider(controls, data.label || "frame", 0, count - 1, 1, 0, (v) => { state.index = v; draw(); },
    (v) => (data.steps ? data.steps[v] : `${v + 1} / ${count}`));
  if (overlays) {
    const wrap = element("label", { class: "control" }, controls);
    const box = element("input", { type: "checkbox" }, wrap);
    wrap.append(` ${data.overlay_label || "overlay"}`);
    box.addEventListener("change", () => { state.overlay = box.checked; draw(); });
  }
  const all = images.flat().concat(overlays ? overlays.flat() : []);
  return Promise.all(all.map((im) => im.decode())).then(draw);
}

const MOUNT = { prt: mountPrt, meshes: mountMeshes, frames: mountFrames };

export function mountAll() {
  const mounted = [];
  document.querySelectorAll("div.viewer").forEach((root) => {
    const data = JSON.parse(document.getElementById(root.dataset.source).textContent);
    try {
      mounted.push(Promise.resolve(MOUNT[root.dataset.kind](root, data)).then(() => root.classList.add("ready")));
    } catch (err) {
      root.classList.add("failed");
      root.append(`viewer failed: ${err}`);
      console.error(err);
    }
  });
  return Promise.all(mounted);
}
