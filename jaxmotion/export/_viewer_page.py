"""The page of :func:`jaxmotion.export.write_viewer_html`: HTML, CSS and a WebGL2 player.

``PAGE`` has three placeholders: ``__TITLE__`` and ``__CAPTION__`` (HTML-escaped
text) and ``__DATA__`` (the JSON payload, with every ``<`` escaped so that it
cannot close its ``<script>`` element). The script reads the payload, decodes its
base64 arrays and draws, with no library and no network access:

- the scene points (``gl.POINTS``, size from the point spacing and distance) in
  their colours or as the affordance heat layer (the same colour formula as
  ``_common.heat_colours``);
- per sample, the decimated body mesh (flat-shaded from screen-space
  derivatives), the pelvis path and the skeleton (lines and joint dots, drawn
  over everything) in the sample's palette colour;
- an orbit camera about a z-up world.

After each draw it sets ``window.jaxmotionViewer = {ready, frame, frames,
samples}`` so that tests and scripts can tell the page is up.
"""

PAGE = r"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>__TITLE__</title>
<style>
  html, body { margin: 0; height: 100%; overflow: hidden; background: #1e2128;
    font: 13px/1.4 system-ui, sans-serif; color: #e8e8e8; }
  #view { display: block; width: 100%; height: 100%; touch-action: none; cursor: grab; }
  #caption { position: absolute; top: 10px; left: 12px; right: 12px; font-size: 15px;
    text-shadow: 0 1px 2px #000; pointer-events: none; }
  #help { position: absolute; top: 36px; left: 12px; opacity: 0.6; font-size: 11px;
    pointer-events: none; }
  #bar { position: absolute; left: 0; right: 0; bottom: 0; display: flex; gap: 10px;
    align-items: center; padding: 8px 12px; background: rgba(20, 22, 28, 0.85); flex-wrap: wrap; }
  #bar button { width: 34px; height: 26px; }
  #time { flex: 1; min-width: 120px; }
  #clock { font-variant-numeric: tabular-nums; min-width: 150px; white-space: nowrap; }
  .swatch { display: inline-block; width: 10px; height: 10px; margin: 0 3px 0 8px;
    border-radius: 2px; }
</style>
</head>
<body>
<canvas id="view"></canvas>
<div id="caption">__CAPTION__</div>
<div id="help">drag: rotate · right-drag or shift-drag: pan · wheel: zoom · double-click: reset
 view · space: play / pause · ← →: step</div>
<div id="bar">
  <button id="play" title="play / pause (space)">&#9654;</button>
  <input id="time" type="range" min="0" max="0" value="0" step="1">
  <span id="clock"></span>
  <label id="bodyToggle"><input id="showBody" type="checkbox" checked> body</label>
  <select id="colouring" title="colour the scene points"></select>
  <span id="legend"></span>
</div>
<script type="application/json" id="jm-data">__DATA__</script>
<script>
"use strict";
(function () {
  const D = JSON.parse(document.getElementById("jm-data").textContent);
  const ARRAYS = { float32: Float32Array, uint8: Uint8Array, uint16: Uint16Array,
    uint32: Uint32Array };

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
  const N = sceneXyz.length / 3;
  const joints = decode(D.joints);
  const aff = D.affordance ? decode(D.affordance.values) : null;
  const body = D.body ? { pos: decode(D.body.positions), faces: decode(D.body.faces),
    count: D.body.positions.shape[2] } : null;

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
  const flat = program(
    `#version 300 es
     in vec3 a_pos; in vec3 a_col; uniform mat4 u_mvp; uniform float u_size; out vec3 v_col;
     void main() { gl_Position = u_mvp * vec4(a_pos, 1.0);
       gl_PointSize = clamp(u_size / gl_Position.w, 1.0, 6.0); v_col = a_col; }`,
    `#version 300 es
     precision mediump float; in vec3 v_col; out vec4 o;
     void main() { o = vec4(v_col, 1.0); }`);
  const shaded = program(
    `#version 300 es
     in vec3 a_pos; uniform mat4 u_mvp; out vec3 v_world;
     void main() { v_world = a_pos; gl_Position = u_mvp * vec4(a_pos, 1.0); }`,
    `#version 300 es
     precision highp float; in vec3 v_world; uniform vec3 u_col; out vec4 o;
     void main() { vec3 n = normalize(cross(dFdx(v_world), dFdy(v_world)));
       float l = 0.35 + 0.65 * abs(dot(n, normalize(vec3(0.3, -0.5, 0.8))));
       o = vec4(u_col * l, 1.0); }`);
  const loc = {
    pos: gl.getAttribLocation(flat, "a_pos"), col: gl.getAttribLocation(flat, "a_col"),
    mvp: gl.getUniformLocation(flat, "u_mvp"), size: gl.getUniformLocation(flat, "u_size"),
    sPos: gl.getAttribLocation(shaded, "a_pos"), sMvp: gl.getUniformLocation(shaded, "u_mvp"),
    sCol: gl.getUniformLocation(shaded, "u_col"),
  };

  function buffer(data, usage, target) {
    const b = gl.createBuffer();
    gl.bindBuffer(target || gl.ARRAY_BUFFER, b);
    gl.bufferData(target || gl.ARRAY_BUFFER, data, usage || gl.STATIC_DRAW);
    return b;
  }
  function attrib(l, buf, size, type, normalized) {
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.enableVertexAttribArray(l);
    gl.vertexAttribPointer(l, size, type || gl.FLOAT, !!normalized, 0, 0);
  }
  function constantColour(rgb) {
    gl.disableVertexAttribArray(loc.col);
    gl.vertexAttrib3f(loc.col, rgb[0], rgb[1], rgb[2]);
  }

  // ---- scene colours: the points' own, or the affordance heat layer
  const sceneBuf = buffer(sceneXyz);
  const colourBuf = buffer(sceneRgb, gl.DYNAMIC_DRAW);
  function inferno(a) {
    const s = D.inferno, x = a * (s.length - 1), i = Math.min(Math.floor(x), s.length - 2);
    const f = x - i;
    return [0, 1, 2].map((c) => s[i][c] * (1 - f) + s[i + 1][c] * f);
  }
  function setColouring(channel) {
    let colours = sceneRgb;
    if (channel !== "rgb") {
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
    gl.bufferData(gl.ARRAY_BUFFER, colours, gl.DYNAMIC_DRAW);
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
    colouring.addEventListener("change", () => { setColouring(colouring.value); redraw(); });
  } else {
    colouring.style.display = "none";
  }

  // ---- per sample: skeleton, pelvis path, body
  const bones = [];
  for (let j = 1; j < J; j++) bones.push(D.parents[j], j);
  const boneBuf = buffer(new Float32Array(bones.length * 3), gl.DYNAMIC_DRAW);
  const jointBuf = buffer(new Float32Array(J * 3), gl.DYNAMIC_DRAW);
  const pathBufs = [];
  for (let s = 0; s < K; s++) {
    const path = new Float32Array(T * 3);
    for (let t = 0; t < T; t++) path.set(joints.subarray(((s * T + t) * J) * 3, ((s * T + t) * J + 1) * 3), t * 3);
    pathBufs.push(buffer(path));
  }
  const planned = D.paths.map((q) => ({ buf: buffer(new Float32Array(q)), n: q.length / 3 }));
  function stepOf(f) {
    const i = D.segments.findIndex((g) => f >= g.first && f <= g.last);
    return i < 0 ? "" : " · step " + (i + 1) + "/" + D.segments.length + ": " + D.segments[i].label;
  }
  let bodyBuf = null, faceBuf = null;
  const showBody = document.getElementById("showBody");
  if (body) {
    bodyBuf = buffer(new Float32Array(body.count * 3), gl.DYNAMIC_DRAW);
    faceBuf = buffer(body.faces, gl.STATIC_DRAW, gl.ELEMENT_ARRAY_BUFFER);
    showBody.addEventListener("change", () => redraw());
  } else {
    document.getElementById("bodyToggle").style.display = "none";
  }
  const legend = document.getElementById("legend");
  if (K > 1) {
    for (let s = 0; s < K; s++) {
      const sw = document.createElement("span");
      sw.className = "swatch";
      sw.style.background = "rgb(" + D.palette[s % D.palette.length].map((c) => Math.round(255 * c)).join(",") + ")";
      legend.appendChild(sw);
      legend.appendChild(document.createTextNode("sample " + s));
    }
  }

  // ---- camera: orbit about a target in a z-up world
  let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < joints.length; i++) {
    lo[i % 3] = Math.min(lo[i % 3], joints[i]);
    hi[i % 3] = Math.max(hi[i % 3], joints[i]);
  }
  const home = { target: [0, 1, 2].map((c) => 0.5 * (lo[c] + hi[c])),
    dist: 3.0 * Math.max(1.5, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])),
    az: -Math.PI / 3, el: Math.PI / 6 };
  let cam = Object.assign({}, home, { target: home.target.slice() });
  const FOV = Math.PI / 4;

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

  // ---- input
  let drag = null;
  canvas.addEventListener("contextmenu", (ev) => ev.preventDefault());
  canvas.addEventListener("pointerdown", (ev) => {
    drag = { x: ev.clientX, y: ev.clientY, pan: ev.button === 2 || ev.shiftKey };
    canvas.setPointerCapture(ev.pointerId);
  });
  canvas.addEventListener("pointerup", () => { drag = null; });
  canvas.addEventListener("pointermove", (ev) => {
    if (!drag) return;
    const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
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

  // ---- timeline
  const slider = document.getElementById("time"), clock = document.getElementById("clock");
  const playButton = document.getElementById("play");
  slider.max = String(T - 1);
  let frame = 0, playing = false, start = 0;
  function setFrame(f) {
    frame = ((f % T) + T) % T;
    slider.value = String(frame);
    clock.textContent = "frame " + (frame + 1) + " / " + T + " · " + (frame / D.fps).toFixed(2) + " s" + stepOf(frame);
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
  let pending = false;
  function redraw() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(draw);
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

    gl.useProgram(flat);
    gl.uniformMatrix4fv(loc.mvp, false, mvp);
    gl.uniform1f(loc.size, pointWorld * pixels);
    attrib(loc.pos, sceneBuf, 3);
    attrib(loc.col, colourBuf, 3, gl.UNSIGNED_BYTE, true);
    gl.drawArrays(gl.POINTS, 0, N);

    if (body && showBody.checked) {
      gl.useProgram(shaded);
      gl.uniformMatrix4fv(loc.sMvp, false, mvp);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, faceBuf);
      for (let s = 0; s < K; s++) {
        const n = body.count * 3, off = (s * T + frame) * n;
        gl.bindBuffer(gl.ARRAY_BUFFER, bodyBuf);
        gl.bufferSubData(gl.ARRAY_BUFFER, 0, body.pos.subarray(off, off + n));
        attrib(loc.sPos, bodyBuf, 3);
        gl.uniform3fv(loc.sCol, D.palette[s % D.palette.length].map((c) => 0.55 + 0.45 * c));
        gl.drawElements(gl.TRIANGLES, body.faces.length, gl.UNSIGNED_INT, 0);
      }
      gl.useProgram(flat);
    }

    gl.disable(gl.DEPTH_TEST);  // the skeletons stay visible through walls and the body
    constantColour([0.55, 0.85, 0.45]);  // planned walking paths, on the floor
    for (const q of planned) { attrib(loc.pos, q.buf, 3); gl.drawArrays(gl.LINE_STRIP, 0, q.n); }
    gl.uniform1f(loc.size, 0.035 * pixels);
    for (let s = 0; s < K; s++) {
      const colour = D.palette[s % D.palette.length];
      const base = (s * T + frame) * J * 3, pose = joints.subarray(base, base + J * 3);
      const segs = new Float32Array(bones.length * 3);
      bones.forEach((j, i) => segs.set(pose.subarray(j * 3, j * 3 + 3), i * 3));
      constantColour(colour.map((c) => 0.5 * c));
      attrib(loc.pos, pathBufs[s], 3);
      gl.drawArrays(gl.LINE_STRIP, 0, T);
      constantColour(colour);
      gl.bindBuffer(gl.ARRAY_BUFFER, boneBuf);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, segs);
      attrib(loc.pos, boneBuf, 3);
      gl.drawArrays(gl.LINES, 0, bones.length);
      gl.bindBuffer(gl.ARRAY_BUFFER, jointBuf);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, pose);
      attrib(loc.pos, jointBuf, 3);
      gl.drawArrays(gl.POINTS, 0, J);
    }
    window.jaxmotionViewer = { ready: true, frame: frame, frames: T, samples: K };
  }

  window.addEventListener("resize", redraw);
  setFrame(0);
})();
</script>
</body>
</html>
"""
