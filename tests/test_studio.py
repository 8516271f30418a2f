"""jaxmotion studio: the API in-process (FastAPI's test client) and the page in headless
Chromium, on one warm studio (the programs are compiled once for the module)."""

import json
import shutil
import socket
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from jaxmotion.studio import Studio, create_app
from jaxmotion.studio.engine import Job

_CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    st = Studio(tmp_path_factory.mktemp("studio"), "demo", video=None, warm=False)
    yield st
    st.close()


@pytest.fixture(scope="module")
def client(studio):
    return TestClient(create_app(studio))


def _chair(studio):
    return next(o for o in studio.room.scene.objects if o["category"] == "chair")


def test_health_scene_and_refusals(client, studio):
    h = client.get("/api/health")
    assert h.status_code == 200 and h.json()["status"] == "ok" and h.json()["room"] == "demo"
    scene = client.get("/api/scene").json()
    assert {"id", "category", "center", "size"} <= set(scene["objects"][0])
    assert {o["category"] for o in scene["objects"]} >= {"chair", "table", "stool"}
    bad = [({"object_id": 99}, 422, "object 99 is not in the room; its objects: 0 (door)"),
           ({}, 422, "say what the person does"),
           ({"text": "x" * 600}, 422, "at most 500"),
           ({"text": "sit", "colour": 1}, 422, "unknown field(s) colour"),
           ({"point": [2.0, 3.0], "text": "sit down"}, 422, "can only be walked to"),
           ({"point": [50.0, 3.0]}, 422, "outside the room"),
           ({"plan": [{"action": "lie", "object": 7}]}, 422, "cannot lie on a stool"),
           ({"plan": [{"action": "sit", "point": [1, 1]}]}, 422, "can only be walked to"),
           ({"text": "sit", "seed": -1}, 422, "seed must be"),
           ({"text": "sit", "samples": 99}, 422, "samples must be"),
           ({"object_id": 4, "point": [1, 1]}, 422, "give one of")]
    for body, status, message in bad:
        r = client.post("/api/generate", json=body)
        assert r.status_code == status and message in r.json()["error"], (body, r.json())
    assert client.post("/api/generate", content=b"[1", headers={
        "content-type": "application/json"}).status_code == 422
    r = client.get("/api/jobs/nope")
    assert r.status_code == 404 and "no job" in r.json()["error"]
    # uploads: the kind, the size, the content; a bad one leaves the room as it was
    r = client.post("/api/scene", files={"file": ("room.exe", b"MZ", "application/x")})
    assert r.status_code == 415 and ".ply" in r.json()["error"]
    r = client.post("/api/scene", files={"file": ("room.ply", b"", "application/octet-stream")})
    assert r.status_code == 400 and "empty" in r.json()["error"]
    r = client.post("/api/scene", files={"file": ("room.ply", b"ply\nnot really",
                                                  "application/octet-stream")})
    assert r.status_code == 400 and r.json()["error"], r.json()
    r = client.post("/api/scene", json={"room": "../../etc"})
    assert r.status_code == 404 and "no room" in r.json()["error"]
    assert client.get("/api/scene").json()["name"] == "demo"
    assert client.get("/api/health").status_code == 200  # still serving


def test_a_click_becomes_a_motion_with_its_files(client, studio):
    chair = _chair(studio)
    r = client.post("/api/generate?wait=true", json={"object_id": chair["id"], "seed": 1})
    assert r.status_code == 200, r.json()
    job = r.json()
    res = job["result"]
    assert job["state"] == "done" and res["target_id"] == chair["id"]
    assert res["text"] == "sit on the chair" and res["pipeline"] == "object-centric"
    joints = np.asarray(res["joints"])
    assert joints.shape[0] == 1 and joints.shape[2:] == (22, 3) and res["fps"] == 30
    assert isinstance(res["notes"], list) and isinstance(res["warnings"], list)
    # seated on the chair at the end: pelvis over its box, at seat height
    lo, hi = np.asarray(chair["bbox_min"]), np.asarray(chair["bbox_max"])
    end = joints[0, -1, 0]
    assert np.all(end[:2] > lo[:2] - 0.15) and np.all(end[:2] < hi[:2] + 0.15), end
    assert 0.4 < end[2] < 0.85, end
    assert studio.idle(300)
    done = client.get(f"/api/jobs/{job['job']}?joints=false").json()
    assert done["files_state"] == "ready" and "joints" not in done["result"]
    assert {"motion.npz", "motion.bvh", "motion.glb", "motion_smplx.npz",
            "viewer.html"} <= set(done["files"])
    npz = client.get(f"/api/jobs/{job['job']}/files/motion.npz")
    assert npz.status_code == 200 and npz.content[:2] == b"PK"
    for name in ("..%2Fjob.json", "job.json", "nope.npz"):  # only its listed files
        assert client.get(f"/api/jobs/{job['job']}/files/{name}").status_code == 404
    # the event stream replays the job and ends once it is written
    events = [json.loads(line[6:]) for line in
              client.get(f"/api/jobs/{job['job']}/events").text.splitlines()
              if line.startswith("data: ")]
    assert events[-1]["state"] == "done" and events[-1]["files_state"] == "ready"
    assert client.get("/api/jobs").json()["jobs"][0]["id"] == job["job"]


def test_stories_by_clicks_with_points_and_their_paths(client, studio):
    chair = _chair(studio)
    plan = [{"action": "walk", "point": [2.0, 3.0]}, {"action": "sit", "object": chair["id"]}]
    preview = client.post("/api/plan", json={"plan": plan}).json()
    assert [s["action"] for s in preview["steps"]] == ["walk", "sit"]
    assert preview["steps"][0]["point"] == [2.0, 3.0] and len(preview["paths"]) >= 1
    # the walk to the point ends there
    path = np.asarray(preview["paths"][0])
    assert np.linalg.norm(path[-1] - [2.0, 3.0]) < 0.1, path[-1]
    r = client.post("/api/generate?wait=true", json={"plan": plan, "seed": 2})
    assert r.status_code == 200, r.json()
    res = r.json()["result"]
    segs = res["segments"]
    assert segs[0]["action"] == "walk" and segs[0]["object"] == -1 and segs[-1]["action"] == "sit"
    joints = np.asarray(res["joints"])[0]
    at = joints[segs[0]["last"], 0, :2]
    assert np.linalg.norm(at - [2.0, 3.0]) < 0.3, at
    speed = np.linalg.norm(np.diff(joints[:, 0], axis=0), axis=-1) * 30
    assert speed.max() < 3.0, speed.max()  # no teleport
    assert joints[-1, 0, 2] < 0.85  # seated


def test_queued_requests_never_mix(client, studio):
    ids = [client.post("/api/generate", json={"text": text, "seed": 3}).json()["job"]
           for text in ("walk to the fridge", "sit on the stool")]
    done = [studio.done(i, 300) for i in ids]
    assert [j.state for j in done] == ["done", "done"]
    cats = {int(o["id"]): o["category"] for o in studio.room.scene.objects}
    assert cats[done[0].summary["target_id"]] == "fridge"
    assert cats[done[1].summary["target_id"]] == "stool"
    assert studio.idle(300)


def test_uploaded_room_is_segmented_and_results_outlive_a_restart(client, studio, tmp_path):
    import trimesh

    from jaxmotion.scene.demo import demo_scene

    bare = demo_scene()  # as a plain point cloud: no labels, no normals
    ply = tmp_path / "my room.ply"
    trimesh.PointCloud(bare.xyz, (bare.rgb * 255).astype(np.uint8)).export(ply)
    r = client.post("/api/scene", files={"file": ("my room.ply", ply.read_bytes(),
                                                  "application/octet-stream")})
    assert r.status_code == 200, r.json()
    room = r.json()
    assert room["name"] == "my room.ply" and len(room["key"]) == 16
    cats = [o["category"] for o in room["objects"]]
    assert "chair" in cats and "table" in cats, cats  # found without labels
    assert any("object" in n.lower() for n in room["notes"]), room["notes"]
    keys = {r["key"] for r in client.get("/api/rooms").json()["rooms"]}
    assert {"demo", room["key"]} <= keys
    assert client.post("/api/scene", json={"room": "demo"}).json()["name"] == "demo"
    # a second studio on the same folder lists the results; a job cut off is failed
    made = client.post("/api/generate?wait=true", json={"text": "walk to the table"}).json()
    assert studio.idle(300) and made["state"] == "done", made
    cut = Job("20260101-000000-abcdef", {"text": "sit"}, "demo", state="running")
    (studio.folder / "jobs" / cut.id / ".x.generate-tmp").mkdir(parents=True)  # as a kill leaves
    (studio.folder / "jobs" / cut.id / "job.json").write_text(json.dumps(cut.record()))
    again = Studio(studio.folder, "demo", video=None, warm=False)
    try:
        listed = {j.id: j for j in again.jobs.values()}
        assert listed[cut.id].state == "failed" and "interrupted" in listed[cut.id].error
        assert not (studio.folder / "jobs" / cut.id / ".x.generate-tmp").exists()
        kept = listed[made["job"]]
        assert kept.state == "done" and "motion.npz" in kept.files
        np.testing.assert_allclose(kept.joints, np.asarray(made["result"]["joints"]), atol=1e-4)
        assert kept.summary["target_id"] == made["result"]["target_id"]
    finally:
        again.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Browser:
    """Headless Chromium driven over the DevTools protocol (a websocket)."""

    def __init__(self, tmp_path, size=(1200, 800)):
        from websockets.sync.client import connect

        self.proc = subprocess.Popen(
            [_CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu",
             "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run",
             "--disable-dev-shm-usage", "--remote-debugging-port=0",
             f"--user-data-dir={tmp_path / 'profile'}", f"--window-size={size[0]},{size[1]}",
             "about:blank"], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
        browser_ws = None
        for line in self.proc.stderr:
            if "DevTools listening on" in line:
                browser_ws = line.split("DevTools listening on ", 1)[1].strip()
                break
        assert browser_ws, "Chromium did not start its DevTools endpoint"
        import urllib.request

        port = browser_ws.split(":")[2].split("/")[0]
        pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json"))
        page = next(p for p in pages if p["type"] == "page")
        self._session = connect(page["webSocketDebuggerUrl"], max_size=2**27, open_timeout=30)
        self.ws = self._session.__enter__()
        self.n = 0

    def send(self, method, **params):
        self.n += 1
        self.ws.send(json.dumps({"id": self.n, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=120))
            if msg.get("id") == self.n:
                assert "error" not in msg, msg
                return msg.get("result", {})

    def eval(self, expression):
        r = self.send("Runtime.evaluate", expression=expression, awaitPromise=True,
                      returnByValue=True)
        assert "exceptionDetails" not in r, r
        return r["result"].get("value")

    def until(self, expression, timeout=120.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            value = self.eval(expression)
            if value:
                return value
            time.sleep(0.25)
        raise AssertionError(f"timed out waiting for {expression}")

    def click(self, x, y):
        for kind in ("mousePressed", "mouseReleased"):
            self.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left",
                      clickCount=1)

    def close(self):
        try:
            self._session.__exit__(None, None, None)
        finally:
            self.proc.kill()
            self.proc.wait(10)


@pytest.mark.skipif(not Path(_CHROMIUM).is_file(),
                    reason="no Chromium (/usr/bin/chromium): .ci/run installs Debian's "
                    "chromium package when it runs as root with apt-get")
@pytest.mark.filterwarnings("ignore::DeprecationWarning:websockets")
def test_the_page_in_headless_chromium(studio, tmp_path):
    import uvicorn
    from PIL import Image

    studio.select_room("demo")
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(create_app(studio), host="127.0.0.1", port=port,
                                           log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.05)
    browser = _Browser(tmp_path)
    try:
        browser.send("Page.navigate", url=f"http://127.0.0.1:{port}/")
        browser.until("document.querySelector('#roomInfo') && "
                      "document.querySelector('#roomInfo').textContent.includes('objects')")
        frame = "document.getElementById('view')"
        browser.until(f"{frame}.contentWindow.jaxmotionViewer && "
                      f"{frame}.contentWindow.jaxmotionViewer.ready")
        chair = _chair(studio)
        lo, hi = np.asarray(chair["bbox_min"]), np.asarray(chair["bbox_max"])
        pts = studio.room.scene.xyz[studio.room.scene.instance == chair["id"]]
        seat = pts[np.argmin(np.linalg.norm(pts[:, :2] - (lo[:2] + hi[:2]) / 2, axis=1)
                             + np.abs(pts[:, 2] - 0.45))]  # a point of the seat, mid-chair
        # where the chair is drawn in the frame, and where the frame is on the page
        x, y = browser.eval(
            f"(() => {{ const r = {frame}.getBoundingClientRect();"
            f" const q = {frame}.contentWindow.jaxmotionViewer.screen({seat.tolist()});"
            " return [r.left + q[0], r.top + q[1]]; })()")
        browser.click(x, y)  # a real click on the canvas: the viewer picks, the page hears
        picked = browser.until("document.getElementById('picked').textContent !== 'nothing'"
                               " && document.getElementById('picked').textContent", timeout=30)
        assert picked == f"chair {chair['id']}", picked
        assert browser.eval("document.getElementById('action').value") == "sit"
        browser.eval("document.getElementById('addStep').click()")
        browser.until("document.querySelectorAll('#steps li').length === 1")
        assert "sit on chair" in browser.eval("document.querySelector('#steps li').textContent")
        browser.eval("document.getElementById('generate').click()")
        state = browser.until("['done','failed'].includes(document.documentElement.dataset.state)"
                              " && document.documentElement.dataset.state", timeout=300)
        assert state == "done", browser.eval("document.getElementById('error').textContent")
        assert "viewer.html" in browser.eval(f"{frame}.getAttribute('src')")
        browser.until(f"{frame}.contentWindow.jaxmotionViewer && "
                      f"{frame}.contentWindow.jaxmotionViewer.samples === 1")
        assert not browser.eval(f"{frame}.contentWindow.jaxmotionErrors.length")
        links = browser.eval("[...document.querySelectorAll('#files a')].map(a => a.href)")
        assert any(h.endswith("motion.npz?download=true") for h in links), links
        status = browser.eval(f"fetch({json.dumps(links[0])}).then(r => r.status)")
        assert status == 200
        assert browser.eval("document.querySelectorAll('#results li').length") >= 1
        # the body is drawn: light blue pixels (sample 0's colour) in the frame
        browser.eval(f"{frame}.contentWindow.document.getElementById('play').click()")
        import base64
        import io

        shot = browser.send("Page.captureScreenshot", format="png")["data"]
        img = np.asarray(Image.open(io.BytesIO(base64.b64decode(shot))).convert("RGB"),
                         np.int64)
        Image.fromarray(img.astype(np.uint8)).save(tmp_path / "studio.png")
        r, g, b = img[:, 360:].reshape(-1, 3).T  # right of the side panel
        body = (b - r > 40) & (g - r > 10) & (b > 150)
        assert body.sum() > 800, body.sum()
    finally:
        browser.close()
        server.should_exit = True
        thread.join(10)
