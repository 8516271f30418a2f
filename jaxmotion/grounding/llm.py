"""A language-model grounder: the object-centric paper's two prompts, over any OpenAI-compatible
chat-completions endpoint (Cen et al. 2024, "Generating Human Motion in 3D Scenes from Text
Descriptions").

1. **Categories**: the instruction and the room's object categories; the model answers the
   target's category and the anchors' (JSON). A free answer ("couch") is mapped to the room's
   category by the lexicon (:func:`jaxmotion.grounding.words.canonical_category`), then by
   the sentence encoder's nearest class name when a
   :class:`~jaxmotion.grounding.similarity.TextSimilarity` is given.
2. **Instance**: the relations of the simplified scene graph (the objects of those categories)
   as sentences ("chair 4 is near table 1") and the candidates; the model answers which one
   is meant. Skipped when the room has one object of the target's category.

:class:`ChatClient` talks to the endpoint with the standard library alone (``urllib``): the
URL, model and key come from ``JAXMOTION_LLM_URL`` (the server's base, e.g.
``http://127.0.0.1:8080/v1`` for llama.cpp's server or ``http://127.0.0.1:11434/v1`` for
Ollama, or the full ``.../chat/completions`` address), ``JAXMOTION_LLM_MODEL`` and
``JAXMOTION_LLM_API_KEY`` (:meth:`ChatClient.from_env`). Each request has a timeout;
connection failures, timeouts, HTTP 408 / 429 / 5xx are retried with exponential backoff;
every failure, and an answer that names nothing in the room, is an :class:`LLMError` (a
:class:`~jaxmotion.errors.GenerateError`) that says what to fix. :func:`llm_ground` returns
the prompts and answers (:attr:`LLMGrounding.exchanges`) so they can be saved.
"""

from __future__ import annotations

import json
import os
import re
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from jaxmotion.errors import GenerateError
from jaxmotion.grounding.objects import object_table
from jaxmotion.grounding.target import Candidates, Instruction, read_instruction
from jaxmotion.grounding.words import canonical_category

__all__ = ["ENV_KEY", "ENV_MODEL", "ENV_URL", "ChatClient", "LLMError", "LLMGrounding",
           "category_prompt", "instance_prompt", "llm_candidates", "llm_ground",
           "match_category"]

ENV_URL, ENV_MODEL, ENV_KEY = "JAXMOTION_LLM_URL", "JAXMOTION_LLM_MODEL", "JAXMOTION_LLM_API_KEY"
_RETRY_STATUS = (408, 409, 425, 429, 500, 502, 503, 504)
_SYSTEM = ("You ground instructions for a person moving in a 3D room. Answer with one JSON "
           "object and nothing else.")


class LLMError(GenerateError):
    """The language model could not be reached or used, or answered nothing usable; the
    message says what to fix."""


@dataclass
class ChatClient:
    """An OpenAI-compatible chat-completions client (standard library only).

    Attributes:
      url: the server's base URL (``.../v1``) or the full ``.../chat/completions`` address.
      model: the model name sent with each request ("" lets a single-model server choose).
      api_key: sent as ``Authorization: Bearer``; None sends none (local servers).
      timeout: seconds per request; retries: further tries after a failed one (connection
        refused or reset, timeout, HTTP 408 / 429 / 5xx); backoff: seconds before the first
        retry, doubled for each next one; sleep: how to wait (tests pass a recorder).
    """

    url: str
    model: str = ""
    api_key: str | None = None
    timeout: float = 30.0
    retries: int = 3
    backoff: float = 1.0
    sleep: Callable[[float], None] = field(default=time.sleep, repr=False)

    @classmethod
    def from_env(cls, env: Mapping[str, str] | None = None, **kwargs) -> ChatClient:
        """A client from ``JAXMOTION_LLM_URL`` / ``_MODEL`` / ``_API_KEY``; :class:`LLMError`
        naming them when the URL is not set."""
        env = os.environ if env is None else env
        url = env.get(ENV_URL, "").strip()
        if not url:
            raise LLMError(f"--grounding llm needs a chat-completions endpoint: set {ENV_URL} "
                           "(e.g. http://127.0.0.1:8080/v1 for llama.cpp's server, "
                           f"http://127.0.0.1:11434/v1 for Ollama), {ENV_MODEL} and, if the "
                           f"server wants one, {ENV_KEY}")
        return cls(url=url, model=env.get(ENV_MODEL, "").strip(),
                   api_key=env.get(ENV_KEY) or None, **kwargs)

    @property
    def endpoint(self) -> str:
        """The chat-completions address."""
        url = self.url.rstrip("/")
        return url if url.endswith("/chat/completions") else url + "/chat/completions"

    def chat(self, messages: list[dict], *, temperature: float = 0.0,
             max_tokens: int = 200) -> str:
        """The model's answer (the first choice's message content) to ``messages``."""
        body = json.dumps({"model": self.model, "messages": messages,
                           "temperature": temperature, "max_tokens": max_tokens}).encode()
        headers = {"Content-Type": "application/json", "Accept": "application/json"}
        if self.api_key:
            headers["Authorization"] = f"Bearer {self.api_key}"
        last = ""
        for attempt in range(int(self.retries) + 1):
            if attempt:
                self.sleep(self.backoff * 2 ** (attempt - 1))
            request = urllib.request.Request(self.endpoint, data=body, headers=headers,
                                             method="POST")
            try:
                with urllib.request.urlopen(request, timeout=self.timeout) as response:
                    return _content(response.read(), self.endpoint)
            except urllib.error.HTTPError as e:
                detail = _detail(e)
                if e.code not in _RETRY_STATUS:
                    raise LLMError(_http_advice(e.code, detail, self)) from None
                last = f"HTTP {e.code}: {detail}"
            except (urllib.error.URLError, TimeoutError, ConnectionError, OSError) as e:
                reason = getattr(e, "reason", e)
                last = f"{type(reason).__name__}: {reason}" if str(reason) else type(
                    reason).__name__
        raise LLMError(f"cannot get an answer from the language model at {self.endpoint} "
                       f"after {int(self.retries) + 1} tries ({last}); start the server, or "
                       f"point {ENV_URL} at one that is running")


def _detail(e: urllib.error.HTTPError) -> str:
    try:
        text = e.read().decode("utf-8", "replace")
    except Exception:  # noqa: BLE001 - the body is only for the message
        text = ""
    return " ".join(text.split())[:200] or str(e.reason)


def _http_advice(code: int, detail: str, client: ChatClient) -> str:
    where = f"the language model at {client.endpoint}"
    if code in (401, 403):
        return (f"{where} refused the request (HTTP {code}: {detail}); set {ENV_KEY} to a key "
                "it accepts")
    if code == 404:
        return (f"{where} has no chat-completions endpoint (HTTP 404: {detail}); {ENV_URL} "
                "should be the server's OpenAI-compatible base, e.g. http://127.0.0.1:8080/v1, "
                f"or the model {client.model!r} ({ENV_MODEL}) is unknown to it")
    return (f"{where} rejected the request (HTTP {code}: {detail}); check {ENV_MODEL} "
            f"({client.model!r}) and that the server speaks the OpenAI chat-completions API")


def _content(raw: bytes, endpoint: str) -> str:
    try:
        reply = json.loads(raw.decode("utf-8"))
        content = reply["choices"][0]["message"]["content"]
    except (ValueError, KeyError, IndexError, TypeError, UnicodeDecodeError):
        shown = raw[:200].decode("utf-8", "replace")
        raise LLMError(f"the server at {endpoint} answered something that is not a chat "
                       f"completion ({shown!r}); {ENV_URL} should point at an "
                       "OpenAI-compatible server") from None
    if not isinstance(content, str) or not content.strip():
        raise LLMError(f"the language model at {endpoint} gave an empty answer; try another "
                       f"model ({ENV_MODEL})")
    return content


# --------------------------------------------------------------------------- the two prompts
def category_prompt(text: str, categories) -> list[dict]:
    """Prompt 1: the target's and the anchors' categories among the room's."""
    return [{"role": "system", "content": _SYSTEM},
            {"role": "user", "content": (
                f"Object categories in the room: {', '.join(categories)}.\n"
                f"Instruction: \"{text}\"\n"
                "Which category is the object the person should walk to, sit on, stand up "
                "from or lie on (the target), and which categories does the instruction use "
                "to say which one it is (the anchors)? Use the categories listed. Answer as "
                '{"target": "<category>", "anchors": ["<category>", ...]}.')}]


def instance_prompt(text: str, candidates, sentences) -> list[dict]:
    """Prompt 2: which of ``candidates`` (object dicts) the instruction means, given the
    simplified scene graph's ``sentences``."""
    names = ", ".join(f"{o['category']} {o['id']}" for o in candidates)
    facts = "\n".join(f"- {s}" for s in sentences) or "- (no relations between them)"
    return [{"role": "system", "content": _SYSTEM},
            {"role": "user", "content": (
                f"Relations between objects in the room:\n{facts}\n"
                f"Instruction: \"{text}\"\n"
                f"Which of {names} is the target of the instruction? Answer as "
                '{"target": "<category> <id>"}.')}]


def _json_object(answer: str) -> dict | None:
    """The first JSON object in an answer (models wrap them in prose or code fences)."""
    decoder = json.JSONDecoder()
    for m in re.finditer(r"\{", answer):
        try:
            value, _ = decoder.raw_decode(answer[m.start():])
        except ValueError:
            continue
        if isinstance(value, dict):
            return value
    return None


def match_category(word, categories, similarity=None) -> str | None:
    """The room's category a free answer means: the same name, the same lexicon class
    ("couch" → a room's ``sofa``), or with ``similarity`` the nearest class name by meaning
    (:func:`~jaxmotion.grounding.similarity.guess_category`); None when none fits."""
    if not isinstance(word, str) or not word.strip():
        return None
    word = word.strip().strip(".\"'").lower()
    for c in categories:
        if c.lower() == word or canonical_category(c) == canonical_category(word):
            return c
    if similarity is not None:
        from jaxmotion.grounding.similarity import guess_category

        guess, _ = guess_category(similarity, word, list(categories))
        return guess
    return None


@dataclass(frozen=True)
class LLMGrounding:
    """What the language model chose (:func:`llm_ground`).

    Attributes:
      target_id: the object chosen; target_category, anchor_categories: prompt 1's answer
        mapped to the room's categories; exchanges: ``{"prompt": messages, "answer": text}``
        per prompt sent; notes: how the answers were read.
    """

    target_id: int
    target_category: str
    anchor_categories: tuple[str, ...] = ()
    exchanges: tuple[dict, ...] = ()
    notes: tuple[str, ...] = ()

    def as_json(self) -> dict:
        """The fields as JSON (to save beside the motion)."""
        return {"target_id": self.target_id, "target_category": self.target_category,
                "anchor_categories": list(self.anchor_categories),
                "exchanges": list(self.exchanges), "notes": list(self.notes)}


def llm_ground(room, text: str, client: ChatClient, *, similarity=None) -> LLMGrounding:
    """The object ``text`` means in ``room``, chosen by the language model in two prompts
    (module docstring). :class:`LLMError` when it cannot be reached or its answers name
    nothing in the room; :class:`~jaxmotion.errors.GenerateError` when the room has no
    object table."""
    from jaxmotion.scene.graph import SceneGraph

    objects = list(object_table(room))
    if not objects:
        raise GenerateError("--grounding llm needs the room's objects (a labelled scan or a "
                            "jaxmotion .npz); this scene has none: use --object ID or "
                            "--grounding auto")
    categories = sorted({o["category"] for o in objects})
    exchanges, notes = [], []
    prompt = category_prompt(text, categories)
    answer = client.chat(prompt)
    exchanges.append({"prompt": prompt, "answer": answer})
    parsed = _json_object(answer)
    if parsed is None and len(answer.split()) <= 3:  # a bare "chair"
        parsed = {"target": answer}
    said = parsed.get("target") if parsed else None
    target = match_category(said, categories, similarity)
    if target is None:
        raise LLMError(f"the language model named {said if said else answer!r} as the target, "
                       f"which is none of this room's categories ({', '.join(categories)})")
    if str(said).strip().lower() != target.lower():
        notes.append(f"the model's target '{said}' read as {target}")
    anchors = []
    raw_anchors = parsed.get("anchors", []) if parsed else []
    for word in raw_anchors if isinstance(raw_anchors, list) else [raw_anchors]:
        found = match_category(word, categories, similarity)
        if found is None:
            notes.append(f"the model's anchor {word!r} is none of the room's categories; left out")
        elif found != target and found not in anchors:
            anchors.append(found)
    candidates = [o for o in objects if o["category"] == target]
    if len(candidates) == 1:
        notes.append(f"the room has one {target}: no second prompt")
        return LLMGrounding(int(candidates[0]["id"]), target, tuple(anchors), tuple(exchanges),
                            tuple(notes))
    keep = {int(o["id"]) for o in objects if o["category"] in (target, *anchors)}
    graph = SceneGraph([o for o in objects if int(o["id"]) in keep])
    prompt = instance_prompt(text, candidates, graph.sentences())
    answer = client.chat(prompt)
    exchanges.append({"prompt": prompt, "answer": answer})
    chosen = _instance(answer, candidates)
    if chosen is None:
        names = ", ".join(f"{o['category']} {o['id']}" for o in candidates)
        raise LLMError(f"the language model answered {answer[:200]!r} to which {target} is "
                       f"meant, which names none of {names}; try another model ({ENV_MODEL}) "
                       "or --grounding auto")
    return LLMGrounding(chosen, target, tuple(anchors), tuple(exchanges), tuple(notes))


def _instance(answer: str, candidates) -> int | None:
    """The candidate id an answer names ("chair 4", {"target": "chair 4"}, "4")."""
    parsed = _json_object(answer)
    said = str(parsed.get("target", "")) if parsed else answer
    ids = {int(o["id"]) for o in candidates}
    found = [int(n) for n in re.findall(r"\d+", said) if int(n) in ids]
    return found[0] if len(set(found)) == 1 else None


def llm_candidates(room, text, client: ChatClient | None = None) -> Candidates:
    """``generate --grounding llm``: the language model's choice (:func:`llm_ground`) as the
    one candidate, asked once per :class:`~jaxmotion.grounding.target.Instruction` (kept in
    its ``memo["llm"]``, where :func:`jaxmotion.grounding.report.explain` finds it).
    ``client``: None reads the endpoint from the environment (:meth:`ChatClient.from_env`)."""
    ins = text if isinstance(text, Instruction) else read_instruction(text)
    if "llm" not in ins.memo:
        ins.memo["llm"] = llm_ground(room, ins.text, client or ChatClient.from_env(),
                                     similarity=ins.similarity)
    got = ins.memo["llm"]
    obj = next(o for o in object_table(room) if int(o["id"]) == got.target_id)
    chose = f"the language model chose {obj['category']} {obj['id']}"
    return Candidates([obj], "llm", (f"{chose} in {len(got.exchanges)} prompt(s)", *got.notes))
