"""The studio's page: one HTML document, no library, nothing loaded from the network.

Left, the controls: the room (upload or drop a file, or pick one the studio knows), the instruction
box, the plan being composed (steps added by clicks, moved up or down, removed), samples and
seed, *Generate*, the stage and progress of the running job (streamed from
``/api/jobs/{id}/events``), the notes and warnings of the result, its downloads, and every
result of the studio's folder (a click opens one again). Right, a frame holding the viewer
page (:mod:`jaxmotion.export.viewer`): the room alone while composing (``/api/scene/view``;
a click on an object or on the floor is sent here by ``postMessage``), the result's
``viewer.html`` once it is written (play, pause, scrub; several samples overlaid, each in its
own colour). The page talks to the server only through the JSON API it documents.

After each change it sets ``data-state`` on ``<html>`` (``idle``, ``working``, ``done``,
``failed``) so that tests and scripts can tell where it stands.
"""

PAGE = r"""<!DOCTYPE html>
<html lang="en" data-state="idle">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>jaxmotion studio</title>
<style>
  html, body { margin: 0; height: 100%; background: #1e2128; color: #e8e8e8;
    font: 13px/1.45 system-ui, sans-serif; }
  body { display: flex; }
  #side { width: 340px; min-width: 280px; overflow-y: auto; overflow-x: hidden; padding: 10px 12px;
    box-sizing: border-box; background: #15171c; border-right: 1px solid #333; }
  #main { flex: 1; position: relative; }
  #view { position: absolute; inset: 0; width: 100%; height: 100%; border: 0; }
  h1 { font-size: 16px; margin: 0 0 8px; }
  h2 { font-size: 12px; text-transform: uppercase; letter-spacing: 0.06em; opacity: 0.7;
    margin: 14px 0 4px; }
  textarea, input, select, button { font: inherit; color: inherit; background: #262a33;
    border: 1px solid #444; border-radius: 4px; }
  textarea { width: 100%; box-sizing: border-box; resize: vertical; padding: 4px 6px; }
  button { padding: 3px 10px; cursor: pointer; }
  button:disabled { opacity: 0.5; cursor: default; }
  button.primary { background: #b7791f; border-color: #d69e2e; color: #111; font-weight: 600; }
  .row { display: flex; gap: 6px; align-items: center; flex-wrap: wrap; margin: 4px 0; }
  .hint { opacity: 0.7; font-size: 12px; }
  #steps { margin: 4px 0; padding-left: 22px; }
  #steps li { margin: 2px 0; }
  #steps li button { padding: 0 5px; margin-left: 3px; font-size: 11px; }
  #picked { color: #ffb640; }
  #progress { width: 100%; height: 6px; background: #333; border-radius: 3px; overflow: hidden; }
  #progress div { height: 100%; width: 0; background: #d69e2e; transition: width 0.2s; }
  #error { color: #ff8a80; white-space: pre-wrap; }
  #notes li, #warnings li { margin: 2px 0; }
  #warnings { color: #ffcc80; }
  #files { display: flex; flex-wrap: wrap; gap: 2px 10px; }
  #files a { color: #90cdf4; }
  #results { list-style: none; padding: 0; margin: 0; }
  #results li { padding: 3px 4px; border-radius: 3px; cursor: pointer; }
  #results li:hover, #results li.open { background: #2d3340; }
  #results .state { opacity: 0.7; font-size: 11px; }
  ul { padding-left: 18px; margin: 4px 0; }
</style>
</head>
<body>
<div id="side">
  <h1>jaxmotion studio</h1>
  <h2>Room</h2>
  <div class="row"><select id="rooms" title="rooms this studio knows"></select>
    <label><button id="uploadButton" type="button">upload…</button>
    <input id="upload" type="file" hidden accept=".ply,.obj,.glb,.off,.stl,.npz"></label></div>
  <div class="hint">or drop a room file (PLY, OBJ, GLB, OFF, STL, NPZ) on the page</div>
  <div id="roomInfo" class="hint"></div>
  <h2>Instruction</h2>
  <textarea id="text" rows="2" maxlength="500"
    placeholder="sit on the chair next to the table"></textarea>
  <div class="hint">Click an object or the floor in the room to pick it; the text and the
    click combine (&ldquo;sit&rdquo; + a clicked stool).</div>
  <div class="row">picked: <span id="picked">nothing</span>
    <button id="clearPick" type="button">clear</button></div>
  <h2>Story</h2>
  <div class="row">
    <select id="action" title="the action of the step a click adds">
      <option value="walk">walk to</option><option value="sit">sit on</option>
      <option value="lie">lie on</option><option value="stand_up">stand up from</option>
    </select>
    <button id="addStep" type="button" title="add the picked object or point as a step">add step</button>
    <button id="clearSteps" type="button">clear</button></div>
  <ol id="steps"></ol>
  <div id="planInfo" class="hint"></div>
  <h2>Generate</h2>
  <div class="row">samples <input id="samples" type="number" min="1" max="8" value="1" style="width:4em">
    seed <input id="seed" type="number" min="0" value="0" style="width:6em"></div>
  <div class="row"><button id="generate" class="primary" type="button">Generate</button>
    <span id="stage" class="hint"></span></div>
  <div id="progress"><div></div></div>
  <div id="error"></div>
  <div id="understood"></div>
  <ul id="notes"></ul>
  <ul id="warnings"></ul>
  <div id="files"></div>
  <h2>Results</h2>
  <ul id="results"></ul>
  <div class="hint" style="margin-top:12px">API: <a href="/api/docs" style="color:#90cdf4">/api/docs</a></div>
</div>
<div id="main"><iframe id="view" title="the room and the motion"></iframe></div>
<script>
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const state = { room: null, pick: null, steps: [], job: null, source: null, paths: [] };
  function setState(s) { document.documentElement.setAttribute("data-state", s); }
  async function api(method, path, body, isForm) {
    const init = { method, headers: {} };
    if (body !== undefined) {
      if (isForm) init.body = body;
      else { init.body = JSON.stringify(body); init.headers["Content-Type"] = "application/json"; }
    }
    const r = await fetch(path, init);
    let data = null;
    try { data = await r.json(); } catch (e) { data = { error: "the studio answered " + r.status }; }
    if (!r.ok) throw new Error((data && data.error) || ("HTTP " + r.status));
    return data;
  }
  function showError(e) { $("error").textContent = e ? String(e.message || e) : ""; }
  function objectName(id) {
    const o = state.room && state.room.objects.find((x) => x.id === id);
    return o ? o.category + " " + o.id : "object " + id;
  }
  function stepLabel(s) {
    const verb = { walk: "walk to", sit: "sit on", lie: "lie on", stand_up: "stand up from" }[s.action];
    return verb + " " + (s.point ? "(" + s.point[0].toFixed(2) + ", " + s.point[1].toFixed(2) + ")" : objectName(s.object));
  }
  function view(src) { if ($("view").getAttribute("src") !== src) $("view").setAttribute("src", src); }
  function sendMarks(paths) {
    if (paths !== undefined) state.paths = paths;
    const marks = state.steps.map((s, i) => ({ object: s.point ? null : s.object, point: s.point || null,
      label: "step " + (i + 1) + " · " + stepLabel(s) }));
    if (state.pick && !state.steps.length) marks.push({ object: state.pick.object, point: state.pick.point,
      label: state.pick.object !== null ? "picked · " + objectName(state.pick.object) : "picked point" });
    const w = $("view").contentWindow;
    if (w) w.postMessage({ type: "jaxmotion-marks", marks, paths: state.paths || [] }, "*");
  }

  // ---- room
  async function loadRooms() {
    const { rooms } = await api("GET", "/api/rooms");
    const sel = $("rooms");
    sel.innerHTML = "";
    for (const r of rooms) {
      const o = document.createElement("option");
      o.value = r.key; o.textContent = r.name; o.selected = r.current;
      sel.appendChild(o);
    }
  }
  function showRoom(room) {
    state.room = room;
    state.pick = null; state.steps = [];
    const cats = {};
    for (const o of room.objects) cats[o.category] = (cats[o.category] || 0) + 1;
    $("roomInfo").textContent = room.name + ": " + room.points.toLocaleString() + " points, " +
      room.objects.length + " objects (" + Object.entries(cats).map(([c, n]) => n + " " + c).join(", ") + ")" +
      (room.notes.length ? " · " + room.notes.join(" · ") : "");
    renderPick(); renderSteps();
    view("/api/scene/view?room=" + encodeURIComponent(room.key));
  }
  $("rooms").addEventListener("change", async () => {
    showError(null);
    try { showRoom(await api("POST", "/api/scene", { room: $("rooms").value })); await loadRooms(); }
    catch (e) { showError(e); }
  });
  $("uploadButton").addEventListener("click", () => $("upload").click());
  $("upload").addEventListener("change", () => { uploadRoom($("upload").files[0]); });
  document.addEventListener("dragover", (ev) => { ev.preventDefault(); });
  document.addEventListener("drop", (ev) => {  // a room file dropped anywhere on the page
    ev.preventDefault();
    if (ev.dataTransfer && ev.dataTransfer.files.length) uploadRoom(ev.dataTransfer.files[0]);
  });
  async function uploadRoom(f) {
    if (!f) return;
    showError(null);
    $("stage").textContent = "reading " + f.name + "…";
    const form = new FormData();
    form.append("file", f, f.name);
    try { showRoom(await api("POST", "/api/scene", form, true)); await loadRooms(); $("stage").textContent = ""; }
    catch (e) { showError(e); $("stage").textContent = ""; }
    $("upload").value = "";
  }

  // ---- picking (messages from the viewer in the frame)
  window.addEventListener("message", (ev) => {
    if (ev.source !== $("view").contentWindow || !ev.data || ev.data.type !== "jaxmotion-pick") return;
    if (!String($("view").getAttribute("src")).startsWith("/api/scene/view")) { view("/api/scene/view?room=" + encodeURIComponent(state.room.key)); return; }
    const d = ev.data;
    const structure = ["floor", "wall", "ceiling"];
    if (d.object !== null && !structure.includes(d.category)) state.pick = { object: d.object, point: null };
    else state.pick = { object: null, point: [d.point[0], d.point[1]] };
    renderPick();
  });
  function renderPick() {
    const p = state.pick;
    $("picked").textContent = !p ? "nothing" : p.object !== null ? objectName(p.object) :
      "floor point (" + p.point[0].toFixed(2) + ", " + p.point[1].toFixed(2) + ")";
    if (p && p.object !== null) {
      const o = state.room.objects.find((x) => x.id === p.object);
      const aff = (o && o.affords) || [];
      const seat = ["chair", "armchair", "sofa", "stool", "bench", "toilet", "couch"].includes(o && o.category) || aff.includes("sit");
      const bed = ["bed"].includes(o && o.category) || aff.includes("lie");
      $("action").value = seat ? "sit" : bed ? "lie" : "walk";
    } else if (p) $("action").value = "walk";
    sendMarks();
  }
  $("clearPick").addEventListener("click", () => { state.pick = null; renderPick(); });

  // ---- the story
  async function renderSteps() {
    const ol = $("steps");
    ol.innerHTML = "";
    state.steps.forEach((s, i) => {
      const li = document.createElement("li");
      li.appendChild(document.createTextNode(stepLabel(s)));
      for (const [label, fn, title] of [["↑", () => move(i, -1), "earlier"], ["↓", () => move(i, 1), "later"], ["✕", () => remove(i), "remove"]]) {
        const b = document.createElement("button");
        b.type = "button"; b.textContent = label; b.title = title;
        b.addEventListener("click", fn);
        li.appendChild(b);
      }
      ol.appendChild(li);
    });
    $("planInfo").textContent = "";
    if (!state.steps.length) { sendMarks([]); return; }
    try {
      const plan = await api("POST", "/api/plan", { plan: planOf(), seed: Number($("seed").value) || 0 });
      const added = plan.steps.length - state.steps.length;
      $("planInfo").textContent = plan.paths.length + " planned walk" + (plan.paths.length === 1 ? "" : "s") +
        (added > 0 ? " · " + added + " stand-up" + (added > 1 ? "s" : "") + " added" : "");
      sendMarks(plan.paths.map((p) => p.flat()));
    } catch (e) { $("planInfo").textContent = String(e.message || e); sendMarks([]); }
  }
  function planOf() { return state.steps.map((s) => s.point ? { action: "walk", point: s.point } : { action: s.action, object: s.object }); }
  function move(i, d) { const j = i + d; if (j < 0 || j >= state.steps.length) return; [state.steps[i], state.steps[j]] = [state.steps[j], state.steps[i]]; renderSteps(); }
  function remove(i) { state.steps.splice(i, 1); renderSteps(); }
  $("addStep").addEventListener("click", () => {
    const p = state.pick;
    if (!p) { showError("pick an object or a point of the floor in the room first"); return; }
    showError(null);
    state.steps.push(p.point ? { action: "walk", point: p.point, object: null } : { action: $("action").value, object: p.object });
    state.pick = null;
    renderPick(); renderSteps();
  });
  $("clearSteps").addEventListener("click", () => { state.steps = []; renderSteps(); });

  // ---- generate, progress, result
  function request() {
    const req = { seed: Number($("seed").value) || 0, samples: Number($("samples").value) || 1 };
    const text = $("text").value.trim();
    if (text) req.text = text;
    if (state.steps.length) req.plan = planOf();
    else if (state.pick && state.pick.object !== null) req.object_id = state.pick.object;
    else if (state.pick) req.point = state.pick.point;
    return req;
  }
  $("generate").addEventListener("click", async () => {
    showError(null);
    for (const id of ["understood", "notes", "warnings", "files"]) $(id).innerHTML = "";
    try {
      const { job } = await api("POST", "/api/generate", request());
      follow(job);
      loadResults();
    } catch (e) { showError(e); setState("failed"); }
  });
  function follow(id) {
    if (state.source) state.source.close();
    state.job = id;
    setState("working");
    $("generate").disabled = true;
    const es = new EventSource("/api/jobs/" + encodeURIComponent(id) + "/events");
    state.source = es;
    es.onmessage = (ev) => {
      const j = JSON.parse(ev.data);
      if (j.id !== state.job) return;
      $("progress").firstElementChild.style.width = Math.round(100 * j.progress) + "%";
      $("stage").textContent = j.state === "queued" ? "queued" : j.stage;
      if (j.state === "failed") { es.close(); $("generate").disabled = false; showError(j.error); setState("failed"); loadResults(); }
      if (j.state === "done") showResult(j);
      if (j.state === "done" && j.files_state !== "writing") { es.close(); $("generate").disabled = false; loadResults(); }
    };
    es.onerror = () => { if (es.readyState === EventSource.CLOSED) $("generate").disabled = false; };
  }
  function showResult(j) {
    const r = j.result || {};
    $("understood").textContent = (r.text ? "“" + r.text + "”" : "") +
      (r.target_id !== null && r.target_id !== undefined ? " · target " + objectName(r.target_id) : "") +
      (r.frames ? " · " + (r.frames / r.fps).toFixed(1) + " s" : "") + (r.pipeline ? " · " + r.pipeline : "");
    for (const [id, list] of [["notes", r.notes || []], ["warnings", r.warnings || []]]) {
      $(id).innerHTML = "";
      for (const n of list) { const li = document.createElement("li"); li.textContent = n; $(id).appendChild(li); }
    }
    const files = j.files || [];
    $("files").innerHTML = "";
    for (const f of files) {
      const a = document.createElement("a");
      a.href = "/api/jobs/" + encodeURIComponent(j.id) + "/files/" + encodeURIComponent(f) + "?download=true";
      a.textContent = f; a.setAttribute("download", f);
      $("files").appendChild(a);
    }
    if (j.files_state === "writing") $("files").appendChild(document.createTextNode(" writing files…"));
    if (files.includes("viewer.html")) view("/api/jobs/" + encodeURIComponent(j.id) + "/files/viewer.html#play=1");
    setState(j.files_state === "writing" ? "working" : "done");
  }
  async function loadResults() {
    const { jobs } = await api("GET", "/api/jobs");
    const ul = $("results");
    ul.innerHTML = "";
    for (const j of jobs) {
      const li = document.createElement("li");
      const req = j.request || {};
      const what = req.text || (req.plan ? req.plan.length + "-step story" : req.point ? "walk to a point" : "");
      li.textContent = what + " ";
      const st = document.createElement("span");
      st.className = "state";
      st.textContent = "· " + j.state + (j.result && j.result.target_id !== null && j.result.target_id !== undefined ? " · target " + j.result.target_id : "");
      li.appendChild(st);
      if (j.id === state.job) li.className = "open";
      li.addEventListener("click", async () => {
        state.job = j.id;
        showError(j.error);
        const full = await api("GET", "/api/jobs/" + encodeURIComponent(j.id) + "?joints=false");
        if (full.state === "done") showResult(full);
        else if (full.state !== "failed") follow(j.id);
        loadResults();
      });
      ul.appendChild(li);
    }
  }
  $("view").addEventListener("load", () => sendMarks());
  (async function start() {
    try {
      await loadRooms();
      showRoom(await api("GET", "/api/scene"));
      await loadResults();
    } catch (e) { showError(e); }
  })();
})();
</script>
</body>
</html>
"""
