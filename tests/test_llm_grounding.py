"""The language-model grounder (jaxmotion.grounding.llm) against a local HTTP server on
127.0.0.1 that speaks the OpenAI chat-completions protocol: the two prompts, free answers,
retries with backoff, timeouts, refusals and nonsense, each a clear error."""

from __future__ import annotations

import json
import socket
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from types import SimpleNamespace

import numpy as np
import pytest

from jaxmotion.errors import GenerateError
from jaxmotion.grounding.llm import (
    ENV_KEY,
    ENV_MODEL,
    ENV_URL,
    ChatClient,
    LLMError,
    llm_ground,
    match_category,
)


def box(i, cat, x, y, w=0.5):
    return {"id": i, "category": cat, "bbox_min": [x, y, 0.0], "bbox_max": [x + w, y + w, 0.9]}


def room():
    """Two chairs (4 by the window, 5 by the door), a sofa, a window, a door."""
    return SimpleNamespace(objects=[box(4, "chair", 0.5, 0.5), box(5, "chair", 4.0, 4.0),
                                    box(6, "sofa", 2.0, 0.0, 1.5), box(7, "window", 0.0, 0.0),
                                    box(8, "door", 4.6, 4.6)])


def completion(text):
    return 200, json.dumps({"id": "x", "object": "chat.completion", "choices": [
        {"index": 0, "message": {"role": "assistant", "content": text},
         "finish_reason": "stop"}]})


class Server:
    """A chat-completions server in a thread: ``reply(request) -> (status, body)`` answers
    each POST (``request``: path, headers, json); ``requests`` records them."""

    def __init__(self, reply, delay=0.0):
        self.reply, self.delay, self.requests = reply, delay, []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                req = {"path": self.path, "headers": dict(self.headers), "json": body}
                outer.requests.append(req)
                time.sleep(outer.delay)
                status, text = outer.reply(req)
                data = text.encode()
                try:
                    self.send_response(status)
                    self.send_header("Content-Type", "application/json")
                    self.send_header("Content-Length", str(len(data)))
                    self.end_headers()
                    self.wfile.write(data)
                except (BrokenPipeError, ConnectionResetError):  # the client gave up
                    pass

            def log_message(self, *args):
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.httpd.shutdown()
        self.httpd.server_close()


def client(url, **kw):
    waits = []
    kw = {"timeout": 5.0, "retries": 2, "backoff": 0.5, "sleep": waits.append, **kw}
    return ChatClient(url, model="tiny-model", **kw), waits


def two_prompts(req):
    """A model that answers prompt 1 in prose with a synonym and prompt 2 with an instance."""
    prompt = req["json"]["messages"][-1]["content"]
    if "Object categories in the room" in prompt:
        return completion('Sure! Here you go:\n```json\n{"target": "Couch", "anchors": []}\n```'
                          if "couch" in prompt else
                          '{"target": "chairs", "anchors": ["front door", "unicorn"]}')
    return completion('{"target": "chair 5"}' if "chair 5 is near door 8" in prompt else "chair 4")


def test_two_prompts_choose_the_instance_and_keep_the_exchanges():
    with Server(two_prompts) as srv:
        c, waits = client(srv.url, api_key="secret")
        got = llm_ground(room(), "sit on the chair by the door", c)
    assert got.target_id == 5 and got.target_category == "chair"
    assert got.anchor_categories == ("door",) and waits == []
    assert any("'unicorn' is none of the room's categories" in n for n in got.notes)
    assert [e["answer"] for e in got.exchanges] == [
        '{"target": "chairs", "anchors": ["front door", "unicorn"]}', '{"target": "chair 5"}']
    first, second = srv.requests
    assert first["path"] == "/v1/chat/completions" and first["json"]["model"] == "tiny-model"
    assert first["headers"]["Authorization"] == "Bearer secret"
    assert "chair, door, sofa, window" in first["json"]["messages"][-1]["content"]
    facts = second["json"]["messages"][-1]["content"]
    assert "chair 5 is near door 8" in facts and "sofa" not in facts  # the simplified graph
    assert json.loads(json.dumps(got.as_json()))["target_id"] == 5


def test_one_object_of_the_class_needs_one_prompt():
    with Server(two_prompts) as srv:
        got = llm_ground(room(), "plop down on the couch", client(srv.url)[0])
    assert got.target_id == 6 and len(got.exchanges) == 1 and len(srv.requests) == 1
    assert "Authorization" not in srv.requests[0]["headers"]  # no key, no header


def test_busy_server_is_retried_with_exponential_backoff():
    answers = iter([(503, "busy"), (429, "slow down"), completion('{"target": "chair 4"}')])
    with Server(lambda req: next(answers)) as srv:
        c, waits = client(srv.url, backoff=0.25)
        assert c.chat([{"role": "user", "content": "hi"}]) == '{"target": "chair 4"}'
    assert waits == [0.25, 0.5] and len(srv.requests) == 3


def test_unreachable_server_is_a_clear_error_after_the_retries():
    with socket.socket() as s:  # a free port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    c, waits = client(f"http://127.0.0.1:{port}/v1/chat/completions", retries=3, backoff=1.0)
    with pytest.raises(LLMError, match=r"after 4 tries .*start the server") as e:
        c.chat([{"role": "user", "content": "hi"}])
    assert isinstance(e.value, GenerateError) and waits == [1.0, 2.0, 4.0]
    assert f"127.0.0.1:{port}/v1/chat/completions " in str(e.value)


def test_a_slow_server_times_out():
    with Server(lambda req: completion("late"), delay=1.0) as srv:
        c, waits = client(srv.url, timeout=0.2, retries=1)
        t0 = time.perf_counter()
        with pytest.raises(LLMError, match="after 2 tries .*timed out"):
            c.chat([{"role": "user", "content": "hi"}])
    assert time.perf_counter() - t0 < 1.5 and waits == [0.5]


@pytest.mark.parametrize("status, match", [
    (401, ENV_KEY), (403, ENV_KEY), (404, "OpenAI-compatible base"), (400, ENV_MODEL)])
def test_refusals_are_not_retried_and_say_what_to_fix(status, match):
    with Server(lambda req: (status, '{"error": "nope"}')) as srv:
        c, waits = client(srv.url)
        with pytest.raises(LLMError, match=match) as e:
            c.chat([{"role": "user", "content": "hi"}])
    assert waits == [] and len(srv.requests) == 1 and "nope" in str(e.value)


@pytest.mark.parametrize("body, match", [
    ("<html>hello</html>", "not a chat completion"),
    (json.dumps({"choices": []}), "not a chat completion"),
    (completion("   ")[1], "empty answer"),
])
def test_answers_that_are_not_completions(body, match):
    with Server(lambda req: (200, body)) as srv, pytest.raises(LLMError, match=match):
        client(srv.url)[0].chat([{"role": "user", "content": "hi"}])


def test_nonsense_answers_name_the_room():
    with (Server(lambda req: completion('{"target": "unicorn"}')) as srv,
          pytest.raises(LLMError, match=r"'unicorn' as the target.*chair, door, sofa")):
        llm_ground(room(), "sit on the chair", client(srv.url)[0])

    def vague(req):
        prompt = req["json"]["messages"][-1]["content"]
        return completion('{"target": "chair"}' if "categories" in prompt else "I am not sure")

    with Server(vague) as srv, pytest.raises(LLMError, match="names none of chair 4, chair 5"):
        llm_ground(room(), "sit on the chair", client(srv.url)[0])
    bare = SimpleNamespace(objects=(), instance=np.full(3, -1), semantic=np.full(3, -1),
                           xyz=np.zeros((3, 3)))  # an unlabelled mesh
    with pytest.raises(GenerateError, match="needs the room's objects"):
        llm_ground(bare, "x", client("http://127.0.0.1:9/v1")[0])


def test_client_from_the_environment():
    with pytest.raises(LLMError, match=f"set {ENV_URL}.*{ENV_MODEL}"):
        ChatClient.from_env({})
    c = ChatClient.from_env({ENV_URL: "http://127.0.0.1:8080/v1/", ENV_MODEL: "qwen",
                             ENV_KEY: "k"}, timeout=3)
    assert c.endpoint == "http://127.0.0.1:8080/v1/chat/completions"
    assert (c.model, c.api_key, c.timeout) == ("qwen", "k", 3)
    assert ChatClient("http://h/x/chat/completions").endpoint == "http://h/x/chat/completions"


def test_free_answers_map_to_the_room_categories():
    cats = ["chair", "coffee table", "fridge", "sofa"]
    assert match_category("Couch.", cats) == "sofa"
    assert match_category("refrigerator", cats) == "fridge"
    assert match_category("COFFEE TABLE", cats) == "coffee table"
    assert match_category("unicorn", cats) is None and match_category(None, cats) is None


def test_generate_with_the_language_model(tiny_runs, tmp_path, monkeypatch):
    """``generate(grounding="llm")`` asks the server once, uses its choice (here the stool the
    words alone would not pick), says so, and saves the prompts and answers."""
    import jaxmotion
    from jaxmotion.scene.demo import demo_scene

    root, _ = tiny_runs
    stools = sorted(o["id"] for o in demo_scene().objects if o["category"] == "stool")

    def model(req):
        prompt = req["json"]["messages"][-1]["content"]
        if "Object categories in the room" in prompt:
            return completion('{"target": "bar stool", "anchors": ["cupboard"]}')
        return completion(f'{{"target": "stool {stools[0]}"}}')

    with Server(model) as srv:
        monkeypatch.setenv(ENV_URL, srv.url)
        monkeypatch.setenv(ENV_MODEL, "tiny-model")
        res = jaxmotion.generate("demo", "perch on the stool by the cupboard", grounding="llm",
                                 checkpoints=(str(root / "adm"), str(root / "amdm")),
                                 steps=2, adm_steps=2, fit_iters=5, pipeline="affordance")
        assert len(srv.requests) == 2  # asked once, not again when explaining
    assert res.target_id == stools[0] and res.grounding == "llm"
    assert res.excluded == tuple(stools[1:])  # the target is known: its class mates left out
    line = json.loads(jaxmotion.export.summary(res))
    assert line["action"] == "sit" and any("language model" in n for n in line["notes"])
    files = res.save(tmp_path / "out", video=None)
    saved = json.loads(files["grounding_llm.json"].read_text())
    assert saved["target_id"] == stools[0] and len(saved["exchanges"]) == 2
    assert "cupboard" in saved["exchanges"][0]["prompt"][-1]["content"]
    monkeypatch.delenv(ENV_URL)
    with pytest.raises(GenerateError, match=f"set {ENV_URL}"):
        jaxmotion.generate("demo", "sit on the stool", grounding="llm",
                           checkpoints=(str(root / "adm"), str(root / "amdm")), steps=2)
