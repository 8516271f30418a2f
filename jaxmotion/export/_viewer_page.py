"""The page of :func:`jaxmotion.export.write_viewer_html`: HTML, CSS and a WebGL2 player.

``PAGE`` has three placeholders: ``__TITLE__`` and ``__CAPTION__`` (HTML-escaped
text) and ``__DATA__`` (the JSON payload, with every ``<`` escaped so that it
cannot close its ``<script>`` element). A first script records every error (uncaught
exceptions, rejected promises, ``console.error``) in ``window.jaxmotionErrors`` and the
``data-errors`` attribute of ``<html>``. The player reads the payload, decodes its
base64 arrays and draws, with no library and no network access:

- the scene points as round splats in their (lit) colours, or as the affordance heat
  layer (the formula of ``_common.heat_colours``, a colour bar in the bar); the
  highlighted object's points (the current step's object in a story, else the target)
  tinted amber; a *cutaway* (on by default): the points above the motion + 0.5 m and the
  points that are not on an object, above 12 cm and more than 0.6 m on the camera's side
  of the bodies, and every object whose box centre lies there (never the target nor a
  step's object) are left out, so walls, ceiling and furniture between the camera and the
  bodies hide nothing;
- per sample, the skinned body: linear blend skinning of the rest mesh in the vertex
  shader (4 joints a vertex, 3 × 4 joint maps as uniforms), lit by a key light and a
  head light in the sample's colour; without a body (or with the body box unticked),
  the skeleton; the pelvis path and the planned walking paths;
- labels over the room: the target's and the story's objects ("chair 4 · target",
  "stool 7 · step 2"), and under the pointer the object there with its id and category
  (its box outlined); labels never cover each other, a panel or a body (a label goes above
  its object, else under it, else above the bodies, else is left out);
- the caption, the target, a story's steps (the current one marked; a click jumps to
  it) and the help in a panel at the top left, the timeline and switches in a bar at the
  bottom, both on opaque backgrounds that nothing is drawn over.

A page with no motion (``K = 0`` samples) shows the room alone, framed whole, without the
timeline; its cutaway leaves out walls and ceiling on the camera's side, never an object.

Embedded in another page (an ``<iframe>``, as the studio does), the viewer talks with its
parent by ``postMessage``: a click (a press and release that does not drag) on the room
sends ``{"type": "jaxmotion-pick", "object": id or null, "category", "point": [x, y, z]}``
(the nearest point under the pointer; ``object`` null for points on no object); the parent
sends ``{"type": "jaxmotion-marks", "marks": [{"object": id or null, "point": [x, y] or
null, "label"}], "paths": [[x, y, x, y, ...], ...]}`` to outline and label the objects and
floor points of a plan being composed and to draw its planned paths (they replace the
page's own).

The page's URL hash sets options: ``#frame=N&body=0&cutaway=0&colour=max&play=1``.
After each draw it sets ``window.jaxmotionViewer = {ready, frame, frames, samples,
body, screen}`` (``screen([x, y, z])``: where a world point is drawn, CSS pixels of the
canvas and depth, or null behind the eye) and the ``data-frame`` attribute of ``<html>`` so that tests and scripts can
tell the page is up.
"""

PAGE = r"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>__TITLE__</title>
<script>
"use strict";
window.jaxmotionErrors = [];
(function () {
  function note(message) {
    window.jaxmotionErrors.push(String(message));
    document.documentElement.setAttribute("data-errors", window.jaxmotionErrors.join(" | "));
  }
  window.addEventListener("error", (ev) => note(ev.message || ev.error || "error"));
  window.addEventListener("unhandledrejection", (ev) => note(ev.reason));
  const original = console.error.bind(console);
  console.error = (...args) => { note(args.join(" ")); original(...args); };
})();
</script>
<style>
  html, body { margin: 0; height: 100%; overflow: hidden; background: #1e2128;
    font: 13px/1.4 system-ui, sans-serif; color: #e8e8e8; }
  #view { display: block; width: 100%; height: 100%; touch-action: none; cursor: grab; }
  .panel { position: absolute; z-index: 3; background: rgba(20, 22, 28, 0.92); }
  #info { top: 0; left: 0; max-width: min(520px, 60%); padding: 8px 12px;
    border-bottom-right-radius: 6px; }
  #caption { font-size: 15px; }
  #target { color: #ffb640; }
  #steps { margin: 4px 0 0; padding-left: 20px; }
  #steps li { cursor: pointer; opacity: 0.75; }
  #steps li.now { opacity: 1; font-weight: 600; color: #ffb640; }
  #info details { font-size: 11px; opacity: 0.75; margin-top: 4px; }
  #bar { left: 0; right: 0; bottom: 0; display: flex; gap: 10px; align-items: center;
    padding: 8px 12px; flex-wrap: wrap; }
  #bar button { width: 34px; height: 26px; }
  #time { flex: 1; min-width: 120px; }
  #clock { font-variant-numeric: tabular-nums; white-space: nowrap; }
  #heat { display: none; align-items: center; gap: 4px; }
  #heat span.bar { width: 90px; height: 10px; border-radius: 2px; }
  .swatch { display: inline-block; width: 10px; height: 10px; margin: 0 3px 0 8px;
    border-radius: 2px; }
  #labels { position: absolute; inset: 0; z-index: 1; pointer-events: none; overflow: hidden; }
  .label, #tip { position: absolute; padding: 1px 6px; border-radius: 3px; white-space: nowrap;
    background: rgba(20, 22, 28, 0.85); font-size: 12px; pointer-events: none; }
  .label.target { color: #ffb640; border: 1px solid #ffb640; }
  #tip { z-index: 2; display: none; border: 1px solid #aaa; }
</style>
</head>
<body>
<canvas id="view"></canvas>
<div id="labels"></div>
<div id="tip"></div>
<div id="info" class="panel">
  <div id="caption">__CAPTION__</div>
  <div id="target"></div>
  <ol id="steps"></ol>
  <details><summary>controls</summary>drag: rotate · right-drag or shift-drag: pan ·
  wheel: zoom · double-click: reset view · space: play / pause · ← →: step · hover: the
  object's id and category</details>
</div>
<div id="bar" class="panel">
  <button id="play" title="play / pause (space)">&#9654;</button>
  <input id="time" type="range" min="0" max="0" value="0" step="1">
  <span id="clock"></span>
  <label id="bodyToggle"><input id="showBody" type="checkbox" checked> body</label>
  <label title="leave out what stands between the camera and the bodies"><input
    id="cutaway" type="checkbox" checked> cutaway</label>
  <select id="colouring" title="colour the scene points"></select>
  <span id="heat">0<span class="bar"></span>1</span>
  <span id="legend"></span>
</div>
<script type="application/json" id="jm-data">__DATA__</script>
<script>
"use strict";
(function () {
  const D = JSON.parse(document.getElementById("jm-data").textContent);
  const ARRAYS = { float32: Float32Array, uint8: Uint8Array, uint16: Uint16Array,
    uint32: Uint32Array, int8: Int8Array };
  const OPTIONS = {};
  for (const part of (location.hash || "").replace(/^#/, "").split("&")) {
    const [key, value] = part.split("=");
    if (key) OPTIONS[key] = value === undefined ? "1" : decodeURIComponent(value);
  }

  function decode(e) {
    const bin = atob(e.b64);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    const raw = new ARRAYS[e.dtype](bytes.buffer);
    if (!e.offset) return raw;
    const d = e.offset.length, out = new Float32Array(raw.length);
    for (let i = 0; i < raw.length; i++) out[i] = e.offset[i % d] + raw[i] * e.step[i % d];
    return out;
  }

  const K = D.num_samples, T = D.num_frames, J = D.parents.length;
  const sceneXyz = decode(D.scene.xyz), sceneRgb = decode(D.scene.rgb);
  const sceneObj = decode(D.scene.instance);
  const N = sceneXyz.length / 3, M = D.objects.length;
  const joints = decode(D.joints);
  const aff = D.affordance ? decode(D.affordance.values) : null;
  const B = D.body;
  const bones = B ? decode(B.bones) : null, NB = B ? B.bones.shape[2] : 0;

  const canvas = document.getElementById("view");
  const gl = canvas.getContext("webgl2", { antialias: true });
  const caption = document.getElementById("caption");
  if (!gl) {
    caption.textContent = "This viewer needs WebGL2, which this browser does not offer.";
    return;
  }

  // ---- shaders
  function program(vs, fs) {
    const p = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      gl.attachShader(p, s);
    }
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    return p;
  }
  function uniforms(p, names) {
    const u = {};
    for (const n of names) u[n] = gl.getUniformLocation(p, n);
    return u;
  }
  // the cutaway, the same rule as cutPoint below
  const points = program(
    `#version 300 es
     layout(location = 0) in vec3 a_pos; layout(location = 1) in vec3 a_col;
     layout(location = 2) in float a_obj;
     uniform mat4 u_mvp; uniform float u_size; uniform sampler2D u_objects;
     uniform vec4 u_cut; uniform bool u_cutaway; uniform vec3 u_tint; out vec3 v_col;
     void main() {
       vec4 state = texelFetch(u_objects, ivec2(int(a_obj + 0.5), 0), 0);
       bool cut = u_cutaway && (state.r > 0.5 || (a_obj < 0.5 && a_pos.z > 0.12 &&
         (a_pos.z > u_cut.w || dot(a_pos.xy, u_cut.xy) > u_cut.z)));
       gl_Position = cut ? vec4(2.0, 2.0, 2.0, 1.0) : u_mvp * vec4(a_pos, 1.0);
       gl_PointSize = cut ? 0.0 : clamp(1.5 * u_size / gl_Position.w, 1.5, 12.0);
       v_col = state.g > 0.5 ? mix(a_col, u_tint, 0.6) : a_col; }`,
    `#version 300 es
     precision mediump float; in vec3 v_col; out vec4 o;
     void main() { vec2 c = gl_PointCoord - 0.5; if (dot(c, c) > 0.25) discard;
       o = vec4(v_col, 1.0); }`);
  const uPoints = uniforms(points, ["u_mvp", "u_size", "u_objects", "u_cut", "u_cutaway",
    "u_tint"]);
  const lines = program(
    `#version 300 es
     layout(location = 0) in vec3 a_pos; uniform mat4 u_mvp; uniform float u_size;
     void main() { gl_Position = u_mvp * vec4(a_pos, 1.0);
       gl_PointSize = clamp(u_size / gl_Position.w, 2.0, 8.0); }`,
    `#version 300 es
     precision mediump float; uniform vec3 u_col; out vec4 o;
     void main() { o = vec4(u_col, 1.0); }`);
  const uLines = uniforms(lines, ["u_mvp", "u_size", "u_col"]);
  let skin = null, uSkin = null;
  if (B) {
    skin = program(
      `#version 300 es
       layout(location = 0) in vec3 a_pos; layout(location = 1) in vec3 a_nrm;
       layout(location = 2) in vec4 a_joint; layout(location = 3) in vec4 a_weight;
       uniform mat4 u_mvp; uniform vec4 u_bones[${3 * NB}];
       out vec3 v_nrm; out vec3 v_world;
       void main() {
         vec4 r0 = vec4(0.0), r1 = vec4(0.0), r2 = vec4(0.0);
         float total = 0.0;
         for (int i = 0; i < 4; i++) {
           int j = int(a_joint[i] + 0.5); float w = a_weight[i];
           r0 += w * u_bones[3 * j]; r1 += w * u_bones[3 * j + 1]; r2 += w * u_bones[3 * j + 2];
           total += w;
         }
         r0 /= total; r1 /= total; r2 /= total;
         vec4 p = vec4(a_pos, 1.0);
         v_world = vec3(dot(r0, p), dot(r1, p), dot(r2, p));
         v_nrm = vec3(dot(r0.xyz, a_nrm), dot(r1.xyz, a_nrm), dot(r2.xyz, a_nrm));
         gl_Position = u_mvp * vec4(v_world, 1.0); }`,
      `#version 300 es
       precision highp float; in vec3 v_nrm; in vec3 v_world;
       uniform vec3 u_col; uniform vec3 u_eye; uniform vec3 u_light; out vec4 o;
       void main() {
         vec3 n = normalize(v_nrm), v = normalize(u_eye - v_world);
         if (dot(n, v) < 0.0) n = -n;
         float key = max(dot(n, u_light), 0.0), head = max(dot(n, v), 0.0);
         float spec = pow(max(dot(n, normalize(u_light + v)), 0.0), 24.0);
         o = vec4(u_col * (0.28 + 0.5 * key + 0.32 * head) + 0.12 * spec, 1.0); }`);
    uSkin = uniforms(skin, ["u_mvp", "u_bones", "u_col", "u_eye", "u_light"]);
  }

  function buffer(data, target) {
    const b = gl.createBuffer();
    gl.bindBuffer(target || gl.ARRAY_BUFFER, b);
    gl.bufferData(target || gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    return b;
  }
  const TYPES = { Float32Array: gl.FLOAT, Uint8Array: gl.UNSIGNED_BYTE,
    Uint16Array: gl.UNSIGNED_SHORT, Int8Array: gl.BYTE, Uint32Array: gl.UNSIGNED_INT };
  function attrib(location, data, size, normalized) {
    buffer(data);
    gl.enableVertexAttribArray(location);
    gl.vertexAttribPointer(location, size, TYPES[data.constructor.name], !!normalized, 0, 0);
  }

  // ---- the scene: points, their colours (own or heat) and per-object state
  const sceneVao = gl.createVertexArray();
  gl.bindVertexArray(sceneVao);
  attrib(0, sceneXyz, 3);
  const colourBuf = buffer(sceneRgb);
  gl.enableVertexAttribArray(1);
  gl.vertexAttribPointer(1, 3, gl.UNSIGNED_BYTE, true, 0, 0);
  attrib(2, sceneObj, 1);
  gl.bindVertexArray(null);
  const objectTex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, objectTex);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  const objectState = new Uint8Array(4 * (M + 1));

  function inferno(a) {
    const s = D.inferno, x = a * (s.length - 1), i = Math.min(Math.floor(x), s.length - 2);
    const f = x - i;
    return [0, 1, 2].map((c) => s[i][c] * (1 - f) + s[i + 1][c] * f);
  }
  let heatShown = false;
  function setColouring(channel) {
    let colours = sceneRgb;
    heatShown = channel !== "rgb";
    if (heatShown) {
      const C = D.affordance.values.shape[1];
      colours = new Uint8Array(N * 3);
      for (let n = 0; n < N; n++) {
        let a = 0;
        if (channel === "max") for (let c = 0; c < C; c++) a = Math.max(a, aff[n * C + c]);
        else a = aff[n * C + Number(channel)];
        a /= 255;
        const grey = 0.8 * (0.299 * sceneRgb[3 * n] + 0.587 * sceneRgb[3 * n + 1] +
          0.114 * sceneRgb[3 * n + 2]) / 255;
        const h = inferno(a);
        for (let c = 0; c < 3; c++) colours[3 * n + c] = Math.round(255 * ((1 - a) * grey + a * h[c]));
      }
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, colourBuf);
    gl.bufferData(gl.ARRAY_BUFFER, colours, gl.STATIC_DRAW);
    document.getElementById("heat").style.display = heatShown ? "inline-flex" : "none";
  }
  const colouring = document.getElementById("colouring");
  if (aff) {
    const options = [["rgb", "scene colours"]];
    if (D.affordance.channels.length > 1) options.push(["max", "affordance: all joints"]);
    D.affordance.channels.forEach((name, c) => options.push([String(c), "affordance: " + name]));
    for (const [value, label] of options) {
      const o = document.createElement("option");
      o.value = value;
      o.textContent = label;
      colouring.appendChild(o);
    }
    const bar = document.querySelector("#heat .bar");
    bar.style.background = "linear-gradient(to right, " + D.inferno.map((c) =>
      "rgb(" + c.map((v) => Math.round(255 * v)).join(",") + ")").join(", ") + ")";
    colouring.addEventListener("change", () => { setColouring(colouring.value); redraw(); });
    if (OPTIONS.colour && options.some((o) => o[0] === OPTIONS.colour)) {
      colouring.value = OPTIONS.colour;
      setColouring(OPTIONS.colour);
    }
  } else {
    colouring.style.display = "none";
  }

  // ---- the bodies: rest meshes skinned in the vertex shader
  const bodyVaos = [];
  let faceType = 0, faceCount = 0;
  if (B) {
    const faces = decode(B.faces), jointIdx = decode(B.joints), weights = decode(B.weights);
    faceType = faces instanceof Uint32Array ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT;
    faceCount = faces.length;
    const shared = { faces: buffer(faces, gl.ELEMENT_ARRAY_BUFFER), joints: buffer(jointIdx),
      weights: buffer(weights) };
    for (const shape of B.shapes) {
      const vao = gl.createVertexArray();
      gl.bindVertexArray(vao);
      attrib(0, decode(shape.positions), 3);
      attrib(1, decode(shape.normals), 3, true);
      gl.bindBuffer(gl.ARRAY_BUFFER, shared.joints);
      gl.enableVertexAttribArray(2);
      gl.vertexAttribPointer(2, 4, TYPES[jointIdx.constructor.name], false, 0, 0);
      gl.bindBuffer(gl.ARRAY_BUFFER, shared.weights);
      gl.enableVertexAttribArray(3);
      gl.vertexAttribPointer(3, 4, gl.UNSIGNED_BYTE, true, 0, 0);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, shared.faces);
      gl.bindVertexArray(null);
      bodyVaos.push(vao);
    }
  }
  const showBody = document.getElementById("showBody");
  if (B) {
    showBody.checked = OPTIONS.body !== "0";
    showBody.addEventListener("change", () => redraw());
  } else {
    document.getElementById("bodyToggle").style.display = "none";
  }
  const cutaway = document.getElementById("cutaway");
  cutaway.checked = OPTIONS.cutaway !== "0";
  cutaway.addEventListener("change", () => redraw());

  // ---- lines: skeletons, pelvis paths, planned paths, the hovered object's box
  const lineVao = gl.createVertexArray();
  gl.bindVertexArray(lineVao);
  const lineBuf = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, lineBuf);
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
  gl.bindVertexArray(null);
  function drawLines(data, mode, colour) {
    gl.uniform3fv(uLines.u_col, colour);
    gl.bindBuffer(gl.ARRAY_BUFFER, lineBuf);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STREAM_DRAW);
    gl.drawArrays(mode, 0, data.length / 3);
  }
  const boneList = [];
  for (let j = 1; j < J; j++) boneList.push(D.parents[j], j);
  const pelvisPaths = [];
  for (let s = 0; s < K; s++) {
    const path = new Float32Array(T * 3);
    for (let t = 0; t < T; t++) path.set(joints.subarray((s * T + t) * J * 3, ((s * T + t) * J + 1) * 3), t * 3);
    pelvisPaths.push(path);
  }
  let planned = D.paths.map((q) => new Float32Array(q));
  let marks = [];  // from the parent page: [{object index or -1, point [x, y] or null, label}]
  function boxEdges(o) {
    const c = [];
    for (let i = 0; i < 8; i++) c.push([i & 1 ? o.hi[0] : o.lo[0], i & 2 ? o.hi[1] : o.lo[1], i & 4 ? o.hi[2] : o.lo[2]]);
    const out = [];
    for (let i = 0; i < 8; i++) for (const b of [1, 2, 4]) if (!(i & b)) out.push(...c[i], ...c[i | b]);
    return new Float32Array(out);
  }
  const sampleColour = (s) => (B ? B.colours[s] : D.palette[s % D.palette.length]);
  const legend = document.getElementById("legend");
  if (K > 1) {
    for (let s = 0; s < K; s++) {
      const sw = document.createElement("span");
      sw.className = "swatch";
      sw.style.background = "rgb(" + sampleColour(s).map((c) => Math.round(255 * c)).join(",") + ")";
      legend.appendChild(sw);
      legend.appendChild(document.createTextNode("sample " + s));
    }
  }

  // ---- objects, the target and a story's steps
  const objectName = (i) => D.objects[i].category + " " + D.objects[i].id;
  if (D.target >= 0) document.getElementById("target").textContent = "target: " + objectName(D.target);
  const stepItems = D.segments.map((g) => {
    const li = document.createElement("li");
    li.textContent = g.label;
    li.addEventListener("click", () => { setPlaying(false); setFrame(g.first); });
    document.getElementById("steps").appendChild(li);
    return li;
  });
  function setMarks(list, paths) {
    for (const l of labels.filter((l) => l.mark)) l.el.remove();
    for (let i = labels.length - 1; i >= 0; i--) if (labels[i].mark) labels.splice(i, 1);
    const index = new Map(D.objects.map((o, i) => [o.id, i]));
    marks = [];
    for (const m of list || []) {
      const i = m.object === null || m.object === undefined ? -1 : (index.has(m.object) ? index.get(m.object) : -1);
      const p = Array.isArray(m.point) && m.point.length >= 2 ? [Number(m.point[0]), Number(m.point[1])] : null;
      if (i < 0 && !p) continue;
      marks.push({ object: i, point: p });
      const el = document.createElement("div");
      el.className = "label target";
      el.textContent = String(m.label || (i >= 0 ? objectName(i) : "here"));
      labelLayer.appendChild(el);
      if (i >= 0) {
        const o = D.objects[i], cx = 0.5 * (o.lo[0] + o.hi[0]), cy = 0.5 * (o.lo[1] + o.hi[1]);
        labels.push({ el, object: i, mark: true, at: [cx, cy, o.hi[2] + 0.15], base: [cx, cy, o.lo[2]] });
      } else {
        labels.push({ el, object: -1, mark: true, at: [p[0], p[1], 0.45], base: [p[0], p[1], 0] });
      }
    }
    if (Array.isArray(paths)) planned = paths.map((q) => new Float32Array(q.length % 2 === 0 && q.length % 3 !== 0 ?
      q.flatMap((v, k) => (k % 2 === 1 ? [v, 0.02] : [v])) : q));
    redraw();
  }
  window.addEventListener("message", (ev) => {
    if (ev.source !== window.parent || !ev.data || ev.data.type !== "jaxmotion-marks") return;
    setMarks(ev.data.marks, ev.data.paths);
  });
  function stepAt(f) { return D.segments.findIndex((g) => f >= g.first && f <= g.last); }
  function highlighted(f) {
    const i = stepAt(f);
    return i >= 0 && D.segments[i].object >= 0 ? D.segments[i].object : D.target;
  }
  const tags = D.objects.map(() => []);
  if (D.target >= 0) tags[D.target].push("target");
  D.segments.forEach((g, i) => { if (g.object >= 0) tags[g.object].push("step " + (i + 1)); });
  const labelLayer = document.getElementById("labels");
  const labels = [];
  tags.forEach((t, i) => {
    if (!t.length) return;
    const el = document.createElement("div");
    el.className = "label" + (i === D.target ? " target" : "");
    el.textContent = objectName(i) + " · " + t.join(", ");
    labelLayer.appendChild(el);
    const o = D.objects[i];
    const cx = 0.5 * (o.lo[0] + o.hi[0]), cy = 0.5 * (o.lo[1] + o.hi[1]);
    labels.push({ el, object: i, at: [cx, cy, o.hi[2] + 0.15], base: [cx, cy, o.lo[2]] });
  });

  // ---- camera: orbit about a target in a z-up world
  let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  const framed = K > 0 ? joints : sceneXyz;  // the motion, or a room alone
  for (let i = 0; i < framed.length; i++) {
    lo[i % 3] = Math.min(lo[i % 3], framed[i]);
    hi[i % 3] = Math.max(hi[i % 3], framed[i]);
  }
  if (K === 0) hi[2] = Math.min(hi[2], 1.4);  // below the ceiling: the cutaway opens the room
  const home = { target: [0, 1, 2].map((c) => 0.5 * (lo[c] + hi[c])),
    dist: (K > 0 ? 2.6 : 1.25) * Math.max(1.6, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])),
    az: -Math.PI / 3, el: K > 0 ? 0.55 : 0.8 };
  if (K === 0) for (const id of ["play", "time", "clock"]) document.getElementById(id).style.display = "none";
  let cam = Object.assign({}, home, { target: home.target.slice() });
  const FOV = Math.PI / 4, LIGHT = [0.35, -0.45, 0.82].map((v) => v / Math.hypot(0.35, 0.45, 0.82));
  const CUT_TOP = hi[2] + 0.5, CUT_MARGIN = 0.6;

  function perspective(aspect, near, far) {
    const f = 1 / Math.tan(FOV / 2), nf = 1 / (near - far);
    return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0];
  }
  function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
  function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function unit(a) { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; }
  function eye() {
    const c = Math.cos(cam.el);
    return [cam.target[0] + cam.dist * c * Math.cos(cam.az), cam.target[1] + cam.dist * c * Math.sin(cam.az),
      cam.target[2] + cam.dist * Math.sin(cam.el)];
  }
  function axes() {  // camera right, up and backward vectors in the world
    const back = unit(sub(eye(), cam.target));
    const right = unit(cross([0, 0, 1], back));
    return [right, cross(back, right), back];
  }
  function viewMatrix() {
    const [r, u, b] = axes(), e = eye();
    return [r[0], u[0], b[0], 0, r[1], u[1], b[1], 0, r[2], u[2], b[2], 0,
      -dot(r, e), -dot(u, e), -dot(b, e), 1];
  }
  function multiply(a, b) {  // column-major 4x4: a · b
    const o = new Float32Array(16);
    for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
      let v = 0;
      for (let k = 0; k < 4; k++) v += a[k * 4 + r] * b[c * 4 + k];
      o[c * 4 + r] = v;
    }
    return o;
  }

  // ---- the cutaway: a vertical plane on the camera's side of the bodies
  let cut = [1, 0, Infinity, Infinity];
  function updateCut() {
    const d = [Math.cos(cam.az), Math.sin(cam.az)];
    let front = K > 0 ? -Infinity : home.target[0] * d[0] + home.target[1] * d[1];
    for (let s = 0; s < K; s++) {
      const p = (s * T + frame) * J * 3;
      front = Math.max(front, joints[p] * d[0] + joints[p + 1] * d[1]);
    }
    cut = [d[0], d[1], front + CUT_MARGIN, CUT_TOP];
    const keep = highlighted(frame), on = cutaway.checked;
    for (let i = 0; i < M; i++) {
      const o = D.objects[i];
      const cx = 0.5 * (o.lo[0] + o.hi[0]), cy = 0.5 * (o.lo[1] + o.hi[1]);
      objectState[4 * (i + 1)] = on && K > 0 && !tags[i].length && i !== keep && (cx * d[0] + cy * d[1] > cut[2] || o.lo[2] > CUT_TOP) ? 255 : 0;
      objectState[4 * (i + 1) + 1] = i === keep && !heatShown ? 255 : 0;
    }
    gl.bindTexture(gl.TEXTURE_2D, objectTex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, M + 1, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, objectState);
  }
  function cutPoint(n) {  // the points shader's rule
    const o = sceneObj[n], z = sceneXyz[3 * n + 2];
    if (!cutaway.checked) return false;
    if (o > 0) return objectState[4 * o] > 0;
    return z > 0.12 && (z > cut[3] || sceneXyz[3 * n] * cut[0] + sceneXyz[3 * n + 1] * cut[1] > cut[2]);
  }

  // ---- input: orbit, pan, zoom, hover
  let drag = null, hover = null, hovered = -1;
  const tip = document.getElementById("tip");
  canvas.addEventListener("contextmenu", (ev) => ev.preventDefault());
  canvas.addEventListener("pointerdown", (ev) => {
    drag = { x: ev.clientX, y: ev.clientY, pan: ev.button === 2 || ev.shiftKey, moved: 0,
      button: ev.button };
    canvas.setPointerCapture(ev.pointerId);
  });
  canvas.addEventListener("pointerup", (ev) => {
    const click = drag && drag.moved < 5 && drag.button === 0;
    drag = null;
    if (click && lastMvp && window.parent !== window) {  // embedded: tell the parent page
      const n = pickPoint(lastMvp, pointWorld * lastPixels, [ev.offsetX, ev.offsetY]);
      if (n < 0) return;
      const o = sceneObj[n] - 1, at = Array.from(sceneXyz.subarray(3 * n, 3 * n + 3));
      window.parent.postMessage({ type: "jaxmotion-pick", object: o >= 0 ? D.objects[o].id : null,
        category: o >= 0 ? D.objects[o].category : null, point: at.map((v) => Math.round(v * 1000) / 1000) }, "*");
    }
  });
  canvas.addEventListener("pointerleave", () => { hover = null; hovered = -1; tip.style.display = "none"; redraw(); });
  canvas.addEventListener("pointermove", (ev) => {
    if (!drag) { hover = [ev.offsetX, ev.offsetY]; redraw(); return; }
    const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
    drag.moved += Math.abs(dx) + Math.abs(dy);
    drag.x = ev.clientX;
    drag.y = ev.clientY;
    if (drag.pan) {
      const [r, u] = axes(), s = 2 * cam.dist * Math.tan(FOV / 2) / canvas.clientHeight;
      for (let c = 0; c < 3; c++) cam.target[c] += s * (-dx * r[c] + dy * u[c]);
    } else {
      cam.az -= dx * 0.008;
      cam.el = Math.max(-1.55, Math.min(1.55, cam.el + dy * 0.008));
    }
    redraw();
  });
  canvas.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    cam.dist *= Math.exp(ev.deltaY * 0.001);
    redraw();
  }, { passive: false });
  canvas.addEventListener("dblclick", () => {
    cam = Object.assign({}, home, { target: home.target.slice() });
    redraw();
  });
  function project(mvp, p) {  // CSS pixels and depth, or null behind the eye
    const x = mvp[0] * p[0] + mvp[4] * p[1] + mvp[8] * p[2] + mvp[12];
    const y = mvp[1] * p[0] + mvp[5] * p[1] + mvp[9] * p[2] + mvp[13];
    const w = mvp[3] * p[0] + mvp[7] * p[1] + mvp[11] * p[2] + mvp[15];
    if (w <= 0.01) return null;
    return [(0.5 + 0.5 * x / w) * canvas.clientWidth, (0.5 - 0.5 * y / w) * canvas.clientHeight, w];
  }
  function pickPoint(mvp, radius, at) {  // the nearest point within reach of ``at`` (pixels)
    let best = -1, depth = Infinity;
    for (let n = 0; n < N; n++) {
      if (cutPoint(n)) continue;
      const q = project(mvp, [sceneXyz[3 * n], sceneXyz[3 * n + 1], sceneXyz[3 * n + 2]]);
      if (!q || q[2] >= depth) continue;
      const r = Math.max(3, Math.min(radius / q[2], 9));
      if ((q[0] - at[0]) ** 2 + (q[1] - at[1]) ** 2 <= r * r) { depth = q[2]; best = n; }
    }
    return best;
  }
  function pick(mvp, radius) {  // the object under the pointer
    const best = pickPoint(mvp, radius, hover);
    return best < 0 ? -1 : sceneObj[best] - 1;
  }

  // ---- timeline
  const slider = document.getElementById("time"), clock = document.getElementById("clock");
  const playButton = document.getElementById("play");
  slider.max = String(T - 1);
  let frame = 0, playing = false, start = 0;
  function setFrame(f) {
    frame = ((f % T) + T) % T;
    slider.value = String(frame);
    const i = stepAt(frame);
    clock.textContent = "frame " + (frame + 1) + " / " + T + " · " + (frame / D.fps).toFixed(2) + " s" +
      (i < 0 ? "" : " · step " + (i + 1) + "/" + D.segments.length);
    stepItems.forEach((li, k) => { li.className = k === i ? "now" : ""; });
    redraw();
  }
  function setPlaying(on) {
    playing = on && T > 1;
    playButton.innerHTML = playing ? "&#10074;&#10074;" : "&#9654;";
    start = performance.now() - (frame / D.fps) * 1000;
    if (playing) requestAnimationFrame(tick);
  }
  function tick(now) {
    if (!playing) return;
    const f = Math.floor(((now - start) / 1000) * D.fps);
    if (f % T !== frame) setFrame(f);
    requestAnimationFrame(tick);
  }
  playButton.addEventListener("click", () => setPlaying(!playing));
  slider.addEventListener("input", () => { setPlaying(false); setFrame(Number(slider.value)); });
  window.addEventListener("keydown", (ev) => {
    if (ev.target instanceof HTMLInputElement && ev.target.type !== "checkbox") return;
    if (ev.key === " ") { ev.preventDefault(); setPlaying(!playing); }
    else if (ev.key === "ArrowRight") { setPlaying(false); setFrame(frame + 1); }
    else if (ev.key === "ArrowLeft") { setPlaying(false); setFrame(frame - 1); }
  });

  // ---- drawing
  const pointWorld = Math.max(0.008, Math.min(0.06, Math.sqrt(2 * Math.max(1,
    (hi[0] - lo[0] + 4) * (hi[1] - lo[1] + 4)) / Math.max(N, 1))));
  let pending = false, lastMvp = null, lastPixels = 1;
  function redraw() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(draw);
  }
  function placeLabels(mvp) {  // greedy: no label over another, a panel or a body
    const placed = [document.getElementById("info"), document.getElementById("bar")]
      .filter((p) => p.getBoundingClientRect).map((p) => p.getBoundingClientRect());
    let body = null;
    for (let s = 0; s < K; s++) for (let j = 0; j < J; j++) {
      const q = project(mvp, joints.subarray(((s * T + frame) * J + j) * 3, ((s * T + frame) * J + j + 1) * 3));
      if (!q) continue;
      const r = 0.25 * canvas.clientHeight / (2 * Math.tan(FOV / 2) * q[2]);  // 25 cm
      body = body || { left: Infinity, right: -Infinity, top: Infinity, bottom: -Infinity };
      body = { left: Math.min(body.left, q[0] - r), right: Math.max(body.right, q[0] + r),
        top: Math.min(body.top, q[1] - r), bottom: Math.max(body.bottom, q[1] + r) };
    }
    const free = (r) => placed.concat(body ? [body] : []).every((p) =>
      r.left >= p.right || r.right <= p.left || r.top >= p.bottom || r.bottom <= p.top);
    for (const l of labels) {
      const q = project(mvp, l.at), base = project(mvp, l.base);
      l.el.style.display = "block";  // measured as shown
      const w = l.el.offsetWidth || 0, h = l.el.offsetHeight || 0;
      const spots = [];  // above the object, under it, above the bodies
      if (q) spots.push([q[0], q[1]]);
      if (base) spots.push([base[0], base[1] + 4 + h]);
      if (q && body) spots.push([q[0], body.top - 4]);
      const r = spots.map(([x, y]) => ({ left: x - w / 2, right: x + w / 2, top: y - h, bottom: y }))
        .find(free);
      l.el.style.display = r ? "block" : "none";
      if (!r) continue;
      l.el.style.left = r.left + "px";
      l.el.style.top = r.top + "px";
      placed.push(r);
    }
  }
  function draw() {
    pending = false;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(0.118, 0.129, 0.157, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    const mvp = multiply(perspective(w / h, cam.dist * 0.01, cam.dist * 100), viewMatrix());
    const pixels = h / (2 * Math.tan(FOV / 2));
    updateCut();

    gl.useProgram(points);
    gl.uniformMatrix4fv(uPoints.u_mvp, false, mvp);
    gl.uniform1f(uPoints.u_size, pointWorld * pixels);
    gl.uniform4fv(uPoints.u_cut, cut);
    gl.uniform1i(uPoints.u_cutaway, cutaway.checked ? 1 : 0);
    gl.uniform3fv(uPoints.u_tint, D.highlight);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, objectTex);
    gl.uniform1i(uPoints.u_objects, 0);
    gl.bindVertexArray(sceneVao);
    gl.drawArrays(gl.POINTS, 0, N);

    const bodies = B && showBody.checked;
    if (bodies) {
      gl.useProgram(skin);
      gl.uniformMatrix4fv(uSkin.u_mvp, false, mvp);
      gl.uniform3fv(uSkin.u_eye, eye());
      gl.uniform3fv(uSkin.u_light, LIGHT);
      for (let s = 0; s < K; s++) {
        const off = (s * T + frame) * NB * 12;
        gl.uniform4fv(uSkin.u_bones, bones.subarray(off, off + NB * 12));
        gl.uniform3fv(uSkin.u_col, B.colours[s]);
        gl.bindVertexArray(bodyVaos[B.shape_of[s]]);
        gl.drawElements(gl.TRIANGLES, faceCount, faceType, 0);
      }
    }

    gl.useProgram(lines);
    gl.uniformMatrix4fv(uLines.u_mvp, false, mvp);
    gl.uniform1f(uLines.u_size, 0.035 * pixels);
    gl.bindVertexArray(lineVao);
    for (const q of planned) drawLines(q, gl.LINE_STRIP, [0.55, 0.85, 0.45]);
    for (let s = 0; s < K; s++) drawLines(pelvisPaths[s], gl.LINE_STRIP, sampleColour(s).map((c) => 0.6 * c));
    if (!bodies) {
      gl.disable(gl.DEPTH_TEST);  // the skeletons stay visible through walls
      for (let s = 0; s < K; s++) {
        const base = (s * T + frame) * J * 3, pose = joints.subarray(base, base + J * 3);
        const segs = new Float32Array(boneList.length * 3);
        boneList.forEach((j, i) => segs.set(pose.subarray(j * 3, j * 3 + 3), i * 3));
        drawLines(segs, gl.LINES, sampleColour(s));
        drawLines(pose, gl.POINTS, sampleColour(s));
      }
    }
    lastMvp = mvp;
    lastPixels = pixels;
    hovered = hover && !drag ? pick(mvp, pointWorld * pixels) : -1;
    gl.disable(gl.DEPTH_TEST);
    for (const m of marks) {
      if (m.object >= 0) drawLines(boxEdges(D.objects[m.object]), gl.LINES, D.highlight);
      else drawLines(new Float32Array([m.point[0], m.point[1], 0, m.point[0], m.point[1], 0.4,
        m.point[0] - 0.15, m.point[1], 0.01, m.point[0] + 0.15, m.point[1], 0.01,
        m.point[0], m.point[1] - 0.15, 0.01, m.point[0], m.point[1] + 0.15, 0.01]), gl.LINES, D.highlight);
    }
    if (hovered >= 0) drawLines(boxEdges(D.objects[hovered]), gl.LINES, [0.95, 0.95, 0.95]);
    gl.bindVertexArray(null);
    tip.style.display = hovered >= 0 ? "block" : "none";
    if (hovered >= 0) {
      tip.textContent = objectName(hovered) + (tags[hovered].length ? " · " + tags[hovered].join(", ") : "");
      tip.style.left = (hover[0] + 14) + "px";
      tip.style.top = (hover[1] + 14) + "px";
    }
    placeLabels(mvp);
    if (!window.jaxmotionViewer) {  // the first draw: any WebGL error is reported
      const error = gl.getError();
      if (error !== gl.NO_ERROR) console.error("WebGL error " + error);
    }
    window.jaxmotionViewer = { ready: true, frame: frame, frames: T, samples: K, body: !!bodies,
      screen: (p) => project(mvp, p) };  // a world point's CSS pixels on the canvas and depth
    document.documentElement.setAttribute("data-frame", String(frame));
  }

  window.addEventListener("resize", redraw);
  setFrame(Number(OPTIONS.frame) || 0);
  if (OPTIONS.play === "1") setPlaying(true);
})();
</script>
</body>
</html>
"""
