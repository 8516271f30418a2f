"""From a room and a sentence to a motion: the main job of jaxmotion.

:func:`generate` runs the affordance pipeline end to end on any scene::

    import jaxmotion
    res = jaxmotion.generate("demo", "sit on the chair next to the table", samples=4, seed=0)
    res.joints        # [K, T, 22, 3] world frame (the scene's), metres, z-up
    res.smplx         # SMPL-X parameters fitted to the joints (jaxopt LBFGS)
    res.save("out")   # motion.npz, motion.bvh, motion.glb, motion.gif, viewer.html

Steps:

1. **Scene**: a path (any mesh or point cloud :func:`jaxmotion.scene.load_scene` reads, a
   ScanNet-style labelled ``.ply``, a jaxmotion ``.npz``), a :class:`~jaxmotion.scene.Scene`,
   or ``"demo"`` (the built-in room, :func:`demo_scene`).
2. **Region**: the AMDM sees a ``crop.size`` square (4 m) of the room, as in training, and
   in training the target object was always inside it. With ``object_id`` the square is
   centred on that object. Otherwise, when the room has an object table (synthetic rooms,
   labelled scans), the candidates are the objects of the first category the text names;
   with ``grounding="auto"`` (the default) a referring expression in the text ("the chair
   closest to the door", "the lamp on the nightstand", Sr3D's relations, parsed by
   :func:`jaxmotion.scene.instructions.parse_instruction`) narrows them by the scene graph's
   geometry (:class:`jaxmotion.scene.graph.SceneGraph`). The ADM's map chooses among what
   is left (``grounding="adm"``: always among all the candidates; the shipped ADMs pick
   among same-class objects no better than chance, see ``docs/results.md``):

   - a **room-view ADM** (trained with ``crop.centre=room``; experimental) is run once on
     its view of the whole room (rooms wider than its 8 m square are tiled) for every sample;
     the candidate the maps light up most is chosen, or without candidates the square is
     centred on the strongest pelvis affordance. The maps are carried to
     the square's points by nearest neighbours (:func:`jaxmotion.geometry.carry_field`).
   - a **crop-view ADM** (the shipped one; trained on the AMDM's squares) is run on a square
     centred on each candidate, and the one its map lights up most is chosen (affordance
     grounding); without candidates, the room is tiled with half-overlapping squares and the
     tile with the strongest predicted pelvis-affordance peak is used.
3. **ADM → AMDM**: affordance maps then motions for ``samples`` seeds, jitted, vmapped
   programs (DDIM with ``adm_steps`` steps for the maps, ``steps`` for the motions). Once the
   target object is known (given as ``object_id``, or chosen with ``grounding="auto"``), the
   other objects of its class in the square are left out of the ADM's map: at every step the
   map's clean estimate is set to "no affordance" on their points (``exclude`` of
   :meth:`~jaxmotion.sample.AffordancePipeline.sample_affordance`), so the sampler puts the
   map elsewhere; the shipped ADM otherwise often lights another chair than the chosen one.
   An ADM that reads a known target (``model.target_input``, the shipped one since session
   11) is also told the target's points, and draws its maps for that object; without a
   known target it is told none (an all-zero mask) and reads the text alone, as for the
   region choice of step 2. A checkpoint folder (the shipped one too) may hold a text-only
   ADM beside it, ``adm_text.safetensors``: that one is used whenever no target is known
   (step 2, and the maps when the region came from tiles); told no target, the ADM that
   reads one draws worse maps. The ADM also draws ``adm_candidates`` maps per sample (default
   16) and the one lighting the target most is kept. (Neither for a room-view ADM, whose map comes from its view.) Then
   the AMDM draws ``motion_candidates`` motions from that map (default 4) and the one whose
   body comes closest to the target at the anchor frame (the last frame; the first when the
   text says to get up from it) is kept.
4. **Body**: SMPL-X parameters fitted to the joints (:func:`jaxmotion.body.fit_joints_to_body`).

The checkpoints default to the ones shipped in the package (``jaxmotion/assets``, trained on the
synthetic world by the commands in ``docs/results.md``); pass ``checkpoints=DIR`` with
``adm.safetensors`` and ``amdm.safetensors`` (and optionally ``adm_text.safetensors``, step 3)
or two training workdirs as a tuple for others.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from jaxmotion._version import __version__

__all__ = [
    "DEFAULT_ADM_CANDIDATES",
    "DEFAULT_ADM_STEPS",
    "DEFAULT_CONSISTENCY",
    "DEFAULT_GUIDANCE",
    "DEFAULT_MOTION_CANDIDATES",
    "DEFAULT_TEXT",
    "GenerateError",
    "Generation",
    "candidate_objects",
    "default_checkpoints",
    "demo_scene",
    "generate",
    "same_class_others",
]

DEFAULT_TEXT = "sit on the chair next to the table"
#: Classifier-free guidance scales (ADM, AMDM) of the shipped checkpoints, chosen on the
#: synthetic validation split (docs/results.md, "Guidance"): w = 5 on the ADM sharpens its
#: maps to the ground truth's share of high-affordance points (success@0.3 75 → 88 %) with
#: goal distance unchanged within the noise; guiding the AMDM made motions end farther away.
DEFAULT_GUIDANCE: tuple[float, float] = (5.0, 1.0)
#: Strength of affordance-consistency guidance on the AMDM (0 = off; see
#: :mod:`jaxmotion.diffusion.affordance_guidance`), chosen on the validation split
#: (docs/results.md, "Consistency guidance").
DEFAULT_CONSISTENCY: float = 0.5
#: ADM maps drawn per sample once the target object is known; the one lighting it most is
#: kept (docs/results.md, "The generate protocol": on 384 validation cases the whole-job goal
#: distance is 0.40 m with the best of 4 maps at 20 steps, 0.33 m with the best of 8 at 10,
#: 0.30 m with the best of 16 at 5, in the same time).
DEFAULT_ADM_CANDIDATES: int = 16
#: DDIM steps of the affordance stage (the motion stage has ``steps``, default 20): how often
#: the ADM's maps light the target depends on how many are drawn, not on their steps (3 to 20),
#: so the time buys candidates.
DEFAULT_ADM_STEPS: int = 5
#: Motions drawn per sample from its map once the target object is known; the one whose body
#: comes closest to the target at the anchor frame is kept (docs/results.md, "Best of M
#: motions").
DEFAULT_MOTION_CANDIDATES: int = 4
DEMO_SEED = 22  # a dining room (L-shaped, 4.3 x 6.0 m) with one table and one chair by it
DEMO_POINTS = 60_000
OUTPUT_FILES = ("motion.npz", "motion.bvh", "motion.glb", "motion.gif", "viewer.html")
_ASSETS = Path(__file__).parent / "assets"


class GenerateError(ValueError):
    """Bad input to :func:`generate`; the message names the problem and the fix."""


# --------------------------------------------------------------------------- inputs
def demo_scene(num_points: int = DEMO_POINTS):
    """The built-in demo room (a synthetic dining room, z-up, metres): ``sample_room(22)``
    scanned with ``num_points`` points; the default size is read from the shipped
    ``assets/demo_room.npz`` (identical, tested; it saves the second it takes to build)."""
    if num_points == DEMO_POINTS and (_ASSETS / "demo_room.npz").is_file():
        from jaxmotion.scene import load_scene

        return load_scene(_ASSETS / "demo_room.npz")
    return build_demo_scene(int(num_points))


@functools.lru_cache(maxsize=2)
def build_demo_scene(num_points: int = DEMO_POINTS):
    """Build the demo room from its seed (what ``assets/demo_room.npz`` holds)."""
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    room = sample_room(DEMO_SEED)
    scene = room_to_scene(room, num_points, np.random.default_rng(DEMO_SEED))
    return dataclasses.replace(scene, name="demo")


def default_checkpoints() -> tuple[Path, Path]:
    """Paths of the shipped ADM and AMDM weights."""
    return _ASSETS / "adm.safetensors", _ASSETS / "amdm.safetensors"


#: In a checkpoint folder (the shipped one too), the ADM used when no target object is known,
#: beside an ``adm.safetensors`` that reads a known target (``model.target_input``): such an
#: ADM, told no target, draws worse maps than one trained on the text alone (docs/results.md,
#: "The ADM told the target"). Optional: without it ``adm.safetensors`` serves both.
TEXT_ADM = "adm_text.safetensors"


def _text_adm(adm_file: Path) -> Path:
    """The ADM for when no target is known: :data:`TEXT_ADM` beside a folder's
    ``adm.safetensors``, else the ADM itself."""
    other = Path(adm_file).with_name(TEXT_ADM)
    return other if Path(adm_file).name == "adm.safetensors" and other.is_file() else Path(adm_file)


def _view(adm_config: dict) -> str:
    """An ADM's ``crop.centre`` (``motion``, the crop view, when its file predates it)."""
    return adm_config.get("crop", {}).get("centre", "motion")


def _text_tokens(adm_config: dict) -> int:
    """How many token states an ADM reads (``model.text_tokens``; 0 = the pooled text)."""
    return int(adm_config.get("model", {}).get("text_tokens", 0))


def _resolve_checkpoints(checkpoints) -> tuple[Path, Path]:
    if checkpoints is None:
        adm, amdm = default_checkpoints()
        if not (adm.is_file() and amdm.is_file()):
            raise GenerateError(
                f"the default checkpoints are missing from {_ASSETS}; reinstall jaxmotion or pass "
                "checkpoints=DIR (a folder with adm.safetensors and amdm.safetensors)")
        return adm, amdm
    if isinstance(checkpoints, (tuple, list)):
        if len(checkpoints) != 2:
            raise GenerateError("checkpoints as a pair must be (ADM, AMDM) workdirs or files")
        from jaxmotion.train.export import weights_path

        paths = [weights_path(p) for p in checkpoints]
    else:
        folder = Path(checkpoints)
        paths = [folder / "adm.safetensors", folder / "amdm.safetensors"]
    for p in paths:
        if not p.is_file():
            raise GenerateError(f"{p}: no such checkpoint file; a checkpoint folder holds "
                                "adm.safetensors and amdm.safetensors")
    return paths[0], paths[1]


@functools.lru_cache(maxsize=4)
def _pipeline(adm: str, amdm: str):
    from jaxmotion.sample import AffordancePipeline

    try:
        return AffordancePipeline.from_files(adm, amdm)
    except (KeyError, ValueError) as e:
        raise GenerateError(f"checkpoints {adm} and {amdm} do not load together: {e}") from e


@functools.lru_cache(maxsize=1)
def _text_encoder():
    from jaxmotion.text import load_text_encoder

    return load_text_encoder("minilm")


@functools.lru_cache(maxsize=1)
def _tokenizer():
    """MiniLM's tokenizer without truncation (to count tokens before the encoder is loaded)."""
    from tokenizers import Tokenizer

    from jaxmotion.text.minilm import minilm_dir

    tok = Tokenizer.from_file(str(minilm_dir() / "tokenizer.json"))
    tok.no_truncation()
    tok.no_padding()
    return tok


def _check_text(text) -> str:
    if not isinstance(text, str):
        raise GenerateError(f"text must be a string, got {type(text).__name__}")
    text = " ".join(text.split())
    if not text:
        raise GenerateError('text is empty; describe the motion, e.g. "sit on the chair"')
    from jaxmotion.text.minilm import max_seq_length

    n, limit = len(_tokenizer().encode(text).ids), max_seq_length()
    if n > limit:
        raise GenerateError(f"text is too long ({n} tokens; the text encoder reads at most "
                            f"{limit}): shorten it to one or two sentences")
    return text


def _cached_one(cache, key, compute):
    """``cache``'s entry ``key``, or ``compute()``'s value, then stored under it (a read-only
    cache is fine: the value is just not kept)."""
    found = cache.get([key])
    if key in found:
        return found[key]
    value = compute()
    try:
        cache.put([key], [value])
    except OSError:
        pass
    return value


def _embed(text: str, cache_dir: Path | None, text_tokens: int = 0):
    """The text condition of ``text`` for a batch of one: the MiniLM embedding ``[1, 384]``,
    or, for an ADM that reads ``text_tokens`` > 0 token states, ``{"pooled" [1, 384],
    "tokens" [1, L, 384], "mask" [1, L]}`` (as
    :meth:`~jaxmotion.sample.AffordancePipeline.embed_text`). Both go through the project's
    on-disk caches (:class:`~jaxmotion.text.EmbeddingCache`,
    :class:`~jaxmotion.text.TokenCache`), keyed by the weights file's size and mtime (its
    checksum would mean reading 90 MB): a repeated command never loads the encoder."""
    from jaxmotion.text import EmbeddingCache, TokenCache, cache_key, pad_tokens
    from jaxmotion.text.minilm import minilm_dir

    def pooled():
        return _text_encoder()([text])[0]

    def words():
        return _text_encoder().token_states([text])[0]

    if cache_dir is None:
        emb, states = pooled(), (words() if text_tokens else None)
    else:
        st = (minilm_dir() / "model.safetensors").stat()
        version = f"size={st.st_size},mtime={st.st_mtime_ns}"
        emb = _cached_one(EmbeddingCache(cache_dir), cache_key("minilm", version, text), pooled)
        states = None
        if text_tokens:
            states = _cached_one(TokenCache(cache_dir.parent / (cache_dir.name + "-tokens")),
                                 cache_key("minilm:tokens", version, text), words)
    emb = np.asarray(emb, np.float32)[None]
    if not text_tokens:
        return emb
    tokens, mask = pad_tokens([states], int(text_tokens), emb.shape[1])
    return {"pooled": emb, "tokens": tokens, "mask": mask}


def _weights_config(path) -> dict:
    """The config stored in a weights file (:func:`jaxmotion.train.export.read_config`)."""
    from jaxmotion.train.export import read_config

    try:
        return read_config(path)
    except (OSError, ValueError) as e:
        raise GenerateError(f"{path}: not a jaxmotion weights file ({e})") from e


def _digest(*parts) -> str:
    """sha256 over strings and files (for the names of cached compiled programs)."""
    import hashlib

    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, Path):
            h.update(part.read_bytes())
        else:
            h.update(repr(part).encode())
        h.update(b"\0")
    return h.hexdigest()[:32]


@functools.lru_cache(maxsize=1)
def _code_digest() -> str:
    """sha256 of jaxmotion's own sources: a cached program is never reused after the code that
    traced it changed (an edit without a version bump included)."""
    root = Path(__file__).parent
    return _digest(*(x for f in sorted(root.rglob("*.py")) for x in (str(f.relative_to(root)), f)))


def _aot_call(cache_dir: Path | None, name: str, fingerprint: str, build, args):
    """``build()(*args)`` through a serialized ``jax.export`` artefact in ``cache_dir``.

    A new process otherwise spends seconds re-tracing the samplers and the LBFGS fit (and
    building the networks) before the persistent compilation cache can even be consulted;
    the artefact holds the traced program (weights included), so a repeated command only
    deserializes it. ``fingerprint`` must change with anything else that changes the program
    (weights, sampler, versions); argument shapes and jaxmotion's sources are added here.
    """
    import jax
    from jax import export as jexport

    specs = jax.tree.map(lambda a: jax.ShapeDtypeStruct(np.shape(a), np.asarray(a).dtype), args)
    fingerprint = _digest(fingerprint, _code_digest(),
                          [(s.shape, str(s.dtype)) for s in jax.tree.leaves(specs)])
    path = None if cache_dir is None else Path(cache_dir) / f"{name}-{fingerprint}.jaxexport"
    if path is not None and path.is_file():
        try:
            return jexport.deserialize(bytearray(path.read_bytes())).call(*args)
        except Exception:  # noqa: BLE001 - a stale or damaged artefact is rebuilt below
            path.unlink(missing_ok=True)
    exp = jexport.export(jax.jit(build()))(*specs)
    if path is not None:
        try:
            from jaxmotion._atomic import atomic_open

            with atomic_open(path, "wb") as f:
                f.write(exp.serialize())
        except (OSError, ImportError):
            pass  # a read-only cache, or no flatbuffers to serialize with: run uncached
    return exp.call(*args)


def _load(scene, num_points: int | None):
    from jaxmotion.scene import Scene, SceneError, load_scene

    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, str) and scene == "demo":
        return demo_scene()
    try:
        return load_scene(scene, num_points=num_points)
    except SceneError as e:
        raise GenerateError(str(e)) from e


# --------------------------------------------------------------------------- result
@dataclasses.dataclass
class Generation:
    """The result of :func:`generate` (numpy arrays; K samples, T frames, N crop points).

    Attributes:
      text: the instruction (whitespace-normalised); scene: the whole room.
      joints: ``[K, T, 22, 3]`` SMPL-X body joints in the scene's frame, metres.
      fps: frames per second; mask: ``[T]`` valid frames.
      smplx: ``global_orient [K,T,3]``, ``body_pose [K,T,21,3]``, ``transl [K,T,3]``,
        ``betas [K,10]`` (axis-angle, SMPL-X conventions), or empty without fitting.
      fit_error: ``[K]`` mean joint distance (m) between the fitted body and ``joints``.
      crop_xyz ``[N,3]`` (scene frame), crop_rgb ``[N,3]`` in [0, 1]: the points the models saw.
      affordance: ``[K, N, 6]`` the ADM's maps (pelvis, feet, neck, wrists) in [0, 1] on the
        crop's points (carried from the room view for a room-view ADM).
      view_xyz ``[M,3]`` (scene frame), view_affordance ``[K, M, 6]``: a room-view ADM's input
        points and its maps on them (None for a crop-view ADM).
      rotation ``[3,3]``, shift ``[3]``: the crop frame, ``x_scene = x_crop @ rotation + shift``.
      object_id: as passed; target_id: the object the region was centred on (``object_id``, or
        the one chosen from the text; None when the region came from tiling the room).
      grounding: how the region was chosen: ``object_id``, ``scene graph`` (the text's
        relation singled the object out), ``class`` (the only object of the named class),
        ``adm`` (the ADM's map chose among candidates) or ``adm peak`` (no candidates).
      excluded: ids of the objects the ADM's map was kept off (the other objects of the
        target's class, once the target was known; step 3 of the module docstring).
      seed, steps: as passed; adm_steps: the ADM stage's DDIM steps used; guidance: the
        ``(ADM, AMDM)`` guidance scales used;
      consistency: the affordance-consistency strength used (0 = off).
      adm_candidates: ADM maps drawn per sample (the one lighting the target most kept); 1
        when the target was not known before sampling.
      motion_candidates: motions drawn per sample from its map (the one reaching the target
        kept); 1 when the target was not known.
      timings: seconds per stage.
    """

    text: str
    scene: Any
    joints: np.ndarray
    fps: float
    mask: np.ndarray
    smplx: dict
    fit_error: np.ndarray
    crop_xyz: np.ndarray
    crop_rgb: np.ndarray
    affordance: np.ndarray
    rotation: np.ndarray
    shift: np.ndarray
    object_id: int | None
    target_id: int | None
    seed: int
    steps: int
    timings: dict
    guidance: tuple[float, float] = (1.0, 1.0)
    consistency: float = 0.0
    view_xyz: np.ndarray | None = None
    view_affordance: np.ndarray | None = None
    grounding: str = ""
    excluded: tuple[int, ...] = ()
    adm_candidates: int = 1
    adm_steps: int = 0
    motion_candidates: int = 1

    @property
    def num_samples(self) -> int:
        return self.joints.shape[0]

    def __repr__(self):
        k, t = self.joints.shape[:2]
        return (f"Generation({self.text!r}, samples={k}, frames={t}, fps={self.fps:g}, "
                f"scene={self.scene.name!r})")

    def save(self, out, *, video: str | None = "gif", bvh_sample: int = 0) -> dict[str, Path]:
        """Write the outputs into folder ``out`` (created); returns ``{name: path}``.

        ``motion.npz`` (every field), ``motion.bvh`` (sample ``bvh_sample``), ``motion.glb``
        (skinned mannequins with the room), ``motion.gif`` / ``motion.mp4`` (``video="gif"|"mp4"``,
        None to skip) and ``viewer.html``. Files are built in a temporary folder and moved in
        at the end, so an error leaves no half-written output.
        """
        from jaxmotion import export

        if video not in (None, "gif", "mp4"):
            raise GenerateError(f"video must be 'gif', 'mp4' or None, got {video!r}")
        if not self.smplx:
            raise GenerateError("this result has no SMPL-X fit (fit=False): BVH and GLB need it")
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        written: dict[str, Path] = {}
        with tempfile.TemporaryDirectory(prefix=".generate-", dir=out) as tmp:
            tmp = Path(tmp)
            with open(tmp / "motion.npz", "wb") as f:
                np.savez(f, joints=self.joints.astype(np.float32), fps=np.float32(self.fps),
                         mask=self.mask, text=np.array(self.text),
                         **{k: np.asarray(v, np.float32) for k, v in self.smplx.items()},
                         fit_error=self.fit_error.astype(np.float32),
                         scene_rotation=self.rotation.astype(np.float32),
                         scene_shift=self.shift.astype(np.float32),
                         crop_xyz=self.crop_xyz.astype(np.float32),
                         affordance=self.affordance.astype(np.float16),
                         object_id=np.int64(-1 if self.object_id is None else self.object_id),
                         target_id=np.int64(-1 if self.target_id is None else self.target_id),
                         seed=np.int64(self.seed), steps=np.int64(self.steps),
                         guidance=np.asarray(self.guidance, np.float32),
                         consistency=np.float32(self.consistency),
                         scene_name=np.array(self.scene.name),
                         grounding=np.array(self.grounding),
                         excluded=np.asarray(self.excluded, np.int64),
                         adm_candidates=np.int64(self.adm_candidates),
                         adm_steps=np.int64(self.adm_steps),
                         motion_candidates=np.int64(self.motion_candidates),
                         **({} if self.view_xyz is None else {
                             "view_xyz": self.view_xyz.astype(np.float32),
                             "view_affordance": self.view_affordance.astype(np.float16)}))
            p = self.smplx
            i = int(bvh_sample)
            export.write_bvh(tmp / "motion.bvh", p["global_orient"][i], p["body_pose"][i],
                             p["transl"][i], p["betas"][i], self.fps)
            xyz, rgb = _subsample(self.scene.xyz, self.scene.rgb, 60_000, self.seed)
            export.write_glb(tmp / "motion.glb", global_orient=p["global_orient"],
                             body_pose=p["body_pose"], transl=p["transl"], betas=p["betas"],
                             fps=self.fps, scene_xyz=xyz, scene_rgb=rgb)
            heat = self._scene_heat(xyz)
            if video:
                export.render_motion_video(tmp / f"motion.{video}", xyz, rgb, self.joints,
                                           self.fps, affordance=None)
            export.write_viewer_html(tmp / "viewer.html", scene_xyz=xyz, scene_rgb=rgb,
                                     joints=self.joints, fps=self.fps, text=self.text,
                                     affordance=heat)
            for f in sorted(tmp.iterdir()):
                os.replace(f, out / f.name)
                written[f.name] = out / f.name
        return written

    def _scene_heat(self, xyz: np.ndarray) -> np.ndarray:
        """The first sample's affordance (strongest channel) carried to ``xyz``: from the room
        view when there is one (nearest view point within 30 cm), else from the crop (within
        10 cm); 0 elsewhere."""
        from scipy.spatial import cKDTree

        src, maps, reach = self.crop_xyz, self.affordance, 0.1
        if self.view_xyz is not None:
            src, maps, reach = self.view_xyz, self.view_affordance, 0.3
        d, idx = cKDTree(src).query(xyz, k=1, distance_upper_bound=reach)
        heat = np.zeros(len(xyz), np.float32)
        ok = np.isfinite(d)
        heat[ok] = maps[0, idx[ok]].max(axis=-1)
        return heat


def _subsample(xyz, rgb, n: int, seed: int):
    if len(xyz) <= n:
        return xyz, rgb
    keep = np.sort(np.random.default_rng(seed).choice(len(xyz), n, replace=False))
    return xyz[keep], rgb[keep]


# --------------------------------------------------------------------------- region
def _centres(lo, hi, size: float) -> list[np.ndarray]:
    """Square centres tiling [lo, hi] (xy) with half-square overlap."""
    axes = []
    for a in range(2):
        ext = hi[a] - lo[a]
        if ext <= size:
            axes.append([0.5 * (lo[a] + hi[a])])
        else:
            n = int(np.ceil((ext - size) / (0.5 * size))) + 1
            axes.append(list(np.linspace(lo[a] + 0.5 * size, hi[a] - 0.5 * size, n)))
    return [np.array([x, y]) for x in axes[0] for y in axes[1]]


def _object_centre(obj, lo, hi, size: float) -> np.ndarray:
    """A square centre on the object's xy box centre, kept inside the room (:func:`_clamp_centre`)."""
    c = 0.5 * (np.asarray(obj["bbox_min"][:2]) + np.asarray(obj["bbox_max"][:2]))
    return _clamp_centre(c, lo, hi, size)


def _clamp_centre(c, lo, hi, size: float) -> np.ndarray:
    """Move a square centre so the square stays inside [lo, hi] where the room allows."""
    half = 0.5 * size
    out = np.array(c, np.float64)
    for a in range(2):
        if hi[a] - lo[a] > size:
            out[a] = np.clip(out[a], lo[a] + half, hi[a] - half)
        else:
            out[a] = 0.5 * (lo[a] + hi[a])
    return out


def _guidance_pair(guidance) -> tuple[float, float]:
    """``None`` / one scale / an ``(ADM, AMDM)`` pair → two positive floats."""
    if guidance is None:
        return DEFAULT_GUIDANCE
    pair = (guidance, guidance) if np.ndim(guidance) == 0 else tuple(guidance)
    try:
        pair = tuple(float(g) for g in pair)
    except (TypeError, ValueError):
        pair = ()
    if len(pair) != 2 or not all(np.isfinite(g) and g > 0 for g in pair):
        raise GenerateError(f"guidance must be a positive number or an (ADM, AMDM) pair of them "
                            f"(1 = no guidance), got {guidance!r}")
    return pair


def _consistency(value) -> float:
    """``None`` → :data:`DEFAULT_CONSISTENCY`; else a float in [0, 1]."""
    if value is None:
        return DEFAULT_CONSISTENCY
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if isinstance(value, bool) or not 0.0 <= v <= 1.0:
        raise GenerateError(f"consistency must be a number in [0, 1] (0 = off), got {value!r}")
    return v


# --------------------------------------------------------------------------- main
def generate(
    scene,
    text: str = DEFAULT_TEXT,
    *,
    object_id: int | None = None,
    samples: int = 1,
    seed: int = 0,
    steps: int = 20,
    adm_steps: int | None = None,
    guidance: float | tuple[float, float] | None = None,
    consistency: float | None = None,
    grounding: str = "auto",
    adm_candidates: int | None = None,
    motion_candidates: int | None = None,
    checkpoints=None,
    num_points: int | None = None,
    fit: bool = True,
    fit_iters: int = 100,
    aot: bool = True,
    progress: bool = False,
) -> Generation:
    """Generate ``samples`` motions of a person doing ``text`` in ``scene``.

    Args:
      scene: ``"demo"``, a path (mesh / point cloud / ``.npz``) or a ``Scene``.
      text: the instruction (one or two sentences).
      object_id: target the object with this instance id instead of finding it from the text.
      samples: K motions, batched by vmap; seed: the PRNG seed (same seed, same output).
      steps: DDIM steps of the motion stage (AMDM).
      adm_steps: DDIM steps of the affordance stage (ADM); None: :data:`DEFAULT_ADM_STEPS`.
      guidance: classifier-free guidance scale, one for both stages or an ``(ADM, AMDM)``
        pair; None: :data:`DEFAULT_GUIDANCE` (1 = no guidance).
      consistency: strength in [0, 1] of affordance-consistency guidance, which moves the
        body so that the motion matches the ADM's map (0 = off); None:
        :data:`DEFAULT_CONSISTENCY`.
      grounding: ``auto``: a relation in the text ("closest to the door") narrows the named
        objects by the scene's geometry before the ADM chooses; ``adm``: the ADM alone
        (module docstring, step 2).
      adm_candidates: once the target object is known (``object_id``, or chosen from the
        text), the ADM draws this many maps per sample and the one that lights the target
        most is kept (step 3); 1 = one map (up to 32); None: :data:`DEFAULT_ADM_CANDIDATES` (16).
        Costs one more ADM pass per candidate (~0.05 s each at 5 steps on 2 CPU cores).
      motion_candidates: once the target object is known, the AMDM draws this many motions
        per sample from its map and the one whose body comes closest to the target at the
        anchor frame is kept (step 3); 1 = one motion (up to 16); None:
        :data:`DEFAULT_MOTION_CANDIDATES`.
      checkpoints: None (shipped), a folder with ``adm.safetensors`` / ``amdm.safetensors``, or
        an ``(adm, amdm)`` pair of workdirs / files.
      num_points: surface samples taken from a mesh (default 100k); point clouds keep theirs.
      fit: fit SMPL-X bodies (needed by :meth:`Generation.save`); fit_iters: LBFGS iterations.
      aot: keep the traced sampling and fitting programs on disk (``jax.export``, next to the
        compilation cache) so that later calls in new processes skip tracing.
      progress: print the stages with their times.
    Raises:
      GenerateError: bad text, scene, object id, sizes or checkpoints (the message says the fix).
    """
    import jax

    from jaxmotion._jax_setup import enable_compilation_cache
    from jaxmotion.config import config_from_dict
    from jaxmotion.data.config import CropConfig
    from jaxmotion.data.crop import CropSpec, crop_at, model_colors
    from jaxmotion.sample import SamplerSpec
    from jaxmotion.scene.instructions import anchor_is_first

    xla_cache = enable_compilation_cache()
    times: dict[str, float] = {}
    t0 = time.perf_counter()

    def lap(name):
        nonlocal t0
        now = time.perf_counter()
        times[name] = now - t0
        t0 = now
        if progress:
            print(f"  {name:<10} {times[name]:6.2f} s", flush=True)

    adm_steps = DEFAULT_ADM_STEPS if adm_steps is None else adm_steps
    for name, v, lo in (("samples", samples, 1), ("steps", steps, 1),
                        ("adm_steps", adm_steps, 1)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < lo:
            raise GenerateError(f"{name} must be an integer ≥ {lo}, got {v!r}")
    if samples > 256:
        raise GenerateError(f"samples={samples} is more than 256; generate in several calls")
    adm_candidates = DEFAULT_ADM_CANDIDATES if adm_candidates is None else adm_candidates
    motion_candidates = (DEFAULT_MOTION_CANDIDATES if motion_candidates is None
                         else motion_candidates)
    for name, v, hi in (("adm_candidates", adm_candidates, 32),
                        ("motion_candidates", motion_candidates, 16)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or not 1 <= v <= hi:
            raise GenerateError(f"{name} must be an integer in [1, {hi}], got {v!r}")
    if grounding not in ("auto", "adm"):
        raise GenerateError(f"grounding must be 'auto' or 'adm', got {grounding!r}")
    adm_file, amdm_file = _resolve_checkpoints(checkpoints)
    text = _check_text(text)
    room = _load(scene, num_points)
    if room.num_points == 0:
        raise GenerateError("the scene has no points")
    mcfg = _weights_config(amdm_file)
    if mcfg.get("task") != "amdm" or "crop" not in mcfg:
        raise GenerateError(f"checkpoints {adm_file} and {amdm_file} do not load together: "
                            f"{amdm_file} is a {mcfg.get('task')!r} checkpoint, not an AMDM one")
    crop_cfg = config_from_dict(CropConfig, mcfg["crop"])
    spec = CropSpec(**{**crop_cfg.__dict__, "rotate": False})
    t_frames, fps = int(mcfg["max_frames"]), 30.0
    lo, hi = room.xyz[:, :2].min(0), room.xyz[:, :2].max(0)
    adm_cfg = _weights_config(adm_file)
    adm_tokens = _text_tokens(adm_cfg)
    room_view = _view(adm_cfg) == "room"
    # the ADM when no target is known (region choice, tiles): the folder's text-only one
    text_adm_file = _text_adm(adm_file)
    if text_adm_file != Path(adm_file):
        t_cfg = _weights_config(text_adm_file)
        if _text_tokens(t_cfg) != adm_tokens or _view(t_cfg) != _view(adm_cfg):
            raise GenerateError(f"{text_adm_file} and {adm_file} must read the text the same way "
                                "(model.text_tokens) and see the same view (crop.centre); "
                                f"remove {text_adm_file.name} to use {Path(adm_file).name} alone")
    get_text_pipe = functools.partial(_pipeline, str(text_adm_file), str(amdm_file))
    emb = _embed(text, xla_cache / "text-embeddings", adm_tokens)
    # the root key's two stage keys (region / room view, then sampling) are split inside the
    # compiled programs, or eagerly only on the paths that need the first: an eager split is
    # an XLA compilation in every fresh process (~0.1 s)
    root = jax.random.key(int(seed))
    stage_key = lambda i: jax.random.split(root)[i]  # noqa: E731
    adm_w, amdm_w = _guidance_pair(guidance)
    adm_sampler = SamplerSpec(method="ddim", steps=int(adm_steps), guidance=adm_w)
    consistency = _consistency(consistency)
    amdm_sampler = SamplerSpec(method="ddim", steps=int(steps), guidance=amdm_w,
                               consistency=consistency)
    aot_dir = xla_cache / "programs" if aot else None
    versions = (jax.__version__, __version__)
    lap("load")

    k = int(samples)
    tile = lambda x: np.ascontiguousarray(np.broadcast_to(x, (k, *np.shape(x))))  # noqa: E731
    view_index = view_maps = None
    if room_view:
        view_index, view_maps = _room_view_maps(
            room, adm_cfg, jax.tree.map(lambda a: a[0], emb), stage_key(0), adm_sampler, k, seed,
            aot_dir, _digest(versions, adm_sampler, text_adm_file), get_text_pipe)
        lap("adm")
    if object_id is not None:
        centre = _object_centre(_object(room, object_id), lo, hi, spec.size)
        chosen, how = int(object_id), "object_id"
    else:
        centre, chosen, how = _find_region(
            room, text, grounding, spec,
            view=(view_index, view_maps) if room_view else None,
            adm=(get_text_pipe, emb, lambda: stage_key(0), adm_sampler, seed))
        if not room_view:
            lap("region")
    rng = np.random.default_rng([int(seed), 1])
    try:
        pick, pts, shift, rot = crop_at(rng, room.xyz, centre, spec)
    except ValueError as e:
        raise GenerateError(f"the scene has no points near the chosen region: {e}") from e
    colors = model_colors(room.rgb[pick])
    # once the target is known (given, or found with the scene graph's help), the other
    # objects of its class are left out of the ADM's map (module docstring, step 3)
    excluded = (same_class_others(object_table(room), chosen)
                if object_id is not None or grounding == "auto" else [])
    exclude = np.isin(room.instance[pick], excluded)
    n_cand = int(adm_candidates) if chosen is not None and not room_view else 1
    n_mot = int(motion_candidates) if chosen is not None else 1
    on_target = tile(room.instance[pick] == (chosen if chosen is not None else -2))
    first = np.full(k, anchor_is_first(text))

    args = (np.asarray(jax.random.key_data(root)), tile(pts), tile(colors),
            jax.tree.map(lambda a: tile(a[0]), emb), np.ones((k, t_frames), bool))
    if room_view:  # the AMDM on the view's maps, carried to the crop (in the crop frame)
        from jaxmotion.sample import AffordancePipeline

        view_in_crop = ((room.xyz[view_index] - shift) @ rot.T).astype(np.float32)
        args = (*args, np.asarray(AffordancePipeline.carry(tile(pts), tile(view_in_crop),
                                                           view_maps)))

    # the maps of a known target come from the ADM told it; else from the text-only one
    main_adm = Path(adm_file) if chosen is not None else text_adm_file

    def build_sampler():
        pipe = _pipeline(str(main_adm), str(amdm_file))
        main = lambda kd: jax.random.split(jax.random.wrap_key_data(kd))[1]  # noqa: E731
        if room_view:
            return lambda kd, p, c, e, m, a, t, f: pipe.sample(
                main(kd), p, c, e, m, amdm=amdm_sampler, affordance=a, target=t,
                motion_candidates=n_mot, anchor_first=f)
        return lambda kd, p, c, e, m, x, t, f: pipe.sample(
            main(kd), p, c, e, m, adm=adm_sampler, amdm=amdm_sampler, exclude=x, target=t,
            candidates=n_cand, motion_candidates=n_mot, anchor_first=f)

    if not room_view:
        args = (*args, tile(exclude))
    args = (*args, on_target, first)
    res = _aot_call(aot_dir, "sample", _digest(versions, adm_sampler, amdm_sampler, n_cand,
                                              n_mot, main_adm, Path(amdm_file)),
                    build_sampler, args)
    res = jax.device_get(res)
    joints = (np.asarray(res["joints"]) @ rot + shift).astype(np.float32)
    aff = np.asarray(res.get("affordance", np.zeros((k, len(pick), 6))), np.float32)
    lap("sample")

    smplx, err = {}, np.full(k, np.nan, np.float32)
    if fit:
        from jaxmotion.body import fit_joints_to_body

        names = ("global_orient", "body_pose", "transl", "betas", "mean_error")

        def build_fit():
            def f(j):
                bf = fit_joints_to_body(j, iters=int(fit_iters), fps=fps)
                return tuple(getattr(bf, n) for n in names)
            return f

        out = jax.device_get(_aot_call(aot_dir, "fit", _digest(versions, int(fit_iters), fps),
                                       build_fit, (joints,)))
        smplx = {n: np.asarray(v, np.float32) for n, v in zip(names[:4], out[:4], strict=True)}
        err = np.asarray(out[4], np.float32)
        lap("fit")
    return Generation(
        text=text, scene=room, joints=joints, fps=fps, mask=np.ones(t_frames, bool), smplx=smplx,
        fit_error=err, crop_xyz=room.xyz[pick].astype(np.float32),
        crop_rgb=room.rgb[pick].astype(np.float32), affordance=aff, rotation=rot, shift=shift,
        object_id=None if object_id is None else int(object_id), target_id=chosen,
        seed=int(seed), steps=int(steps), guidance=(adm_w, amdm_w), consistency=consistency,
        timings=times, grounding=how, excluded=tuple(excluded) if not room_view else (),
        adm_candidates=n_cand, adm_steps=int(adm_steps), motion_candidates=n_mot,
        view_xyz=None if view_index is None else room.xyz[view_index].astype(np.float32),
        view_affordance=None if view_maps is None else np.asarray(view_maps, np.float32),
    )


def _object(room, object_id) -> dict:
    objects = object_table(room)
    if not objects:
        raise GenerateError(f"object {object_id} given but the scene has no objects (no "
                            "per-point instance labels, as a ScanNet-style .ply or a jaxmotion "
                            ".npz has); leave out --object to find the target from the text")
    for o in objects:
        if o["id"] == int(object_id):
            return o
    valid = ", ".join(f"{o['id']} ({o['category']})" for o in objects)
    raise GenerateError(f"unknown object id {object_id}; this scene's objects: {valid}")


# NYU40 class names (the ScanNet benchmark's label ids) for labelled scans; jaxmotion's own
# categories (jaxmotion.scene.furniture.CATEGORY_IDS) take precedence for their ids.
_NYU40 = (
    "wall", "floor", "cabinet", "bed", "chair", "sofa", "table", "door", "window", "bookshelf",
    "picture", "counter", "blinds", "desk", "shelves", "curtain", "dresser", "pillow", "mirror",
    "floor mat", "clothes", "ceiling", "books", "fridge", "tv", "paper", "towel",
    "shower curtain", "box", "whiteboard", "person", "nightstand", "toilet", "sink", "lamp",
    "bathtub", "bag", "otherstructure", "otherfurniture", "otherprop",
)
_STRUCTURE = {"wall", "floor", "ceiling"}
_ALIASES = {"refrigerator": "fridge", "television": "tv", "night stand": "nightstand",
            "couch": "sofa", "bookcase": "bookshelf", "settee": "sofa", "bathroom sink": "sink"}


def object_table(room) -> tuple[dict, ...]:
    """The room's objects; for a labelled scan without a table (per-point ``instance`` and
    ``semantic`` ids only, e.g. a ScanNet ``.ply``) one is derived: per instance, the xy/z
    bounding box of its points and the category of its most common semantic id."""
    if room.objects:
        return tuple(room.objects)
    from jaxmotion.scene.furniture import CATEGORY_IDS

    names = {i + 1: n for i, n in enumerate(_NYU40)}
    names.update({v: k for k, v in CATEGORY_IDS.items()})
    out = []
    for inst in np.unique(room.instance[room.instance >= 0]):
        sel = room.instance == inst
        sem = room.semantic[sel]
        sem = sem[sem >= 0]
        cat = names.get(int(np.bincount(sem).argmax()), "object") if len(sem) else "object"
        if cat in _STRUCTURE:
            continue
        pts = room.xyz[sel]
        out.append({"id": int(inst), "category": cat, "bbox_min": pts.min(0).tolist(),
                    "bbox_max": pts.max(0).tolist()})
    return tuple(out)


def mentioned_objects(room, text: str) -> list[dict]:
    """Objects of the first category the text names (whole words, plural ``s`` allowed,
    a few synonyms such as "couch" → sofa; the earliest mention wins, so in "the chair next
    to the table" it is the chair); ``[]`` when it names none."""
    import re

    low = " " + re.sub(r"[^a-z ]+", " ", text.lower()) + " "
    for alias, name in _ALIASES.items():
        low = re.sub(rf" {alias}(s)? ", f" {name}\\1 ", low)
    objects = object_table(room)
    best, where = None, len(low)
    for cat in sorted({o["category"] for o in objects}, key=len, reverse=True):
        name = cat.replace("_", " ").lower()
        m = re.search(rf" {re.escape(name)}(s|es)? ", low)
        if m and m.start() < where:
            best, where = name, m.start()
    if best is None:
        return []
    return [o for o in objects if o["category"].replace("_", " ").lower() == best]


def _crops(room, centres, spec, seed: int, tag: int):
    """Crops at several centres, skipping ones with no point: a list of
    ``(index into centres, pick, points, colours)``."""
    from jaxmotion.data.crop import crop_at, model_colors

    out = []
    for i, c in enumerate(centres):
        try:
            pick, p, _, _ = crop_at(np.random.default_rng([int(seed), tag, i]), room.xyz, c, spec)
        except ValueError:  # a tile outside an L-shaped room
            continue
        out.append((i, pick, p, model_colors(room.rgb[pick])))
    return out


def _adm_maps(get_pipe, crops, emb, key, sampler) -> np.ndarray:
    import jax

    b = len(crops)
    return np.asarray(jax.device_get(get_pipe().sample_affordance(
        key, np.stack([c[2] for c in crops]), np.stack([c[3] for c in crops]),
        jax.tree.map(lambda a: np.broadcast_to(a[0], (b, *a.shape[1:])), emb), sampler)))


def candidate_objects(room, text: str, grounding: str = "auto") -> tuple[list[dict], str]:
    """The objects the region may be centred on, and how they were found: the objects of the
    category the text names (:func:`mentioned_objects`; ``"class"``), narrowed with
    ``grounding="auto"`` by the relation of the text's referring expression when it parses
    and picks some of them (:func:`jaxmotion.scene.instructions.resolve`; ``"scene graph"``).
    ``([], "")`` when the text names no object of the room."""
    candidates = mentioned_objects(room, text)
    if grounding != "auto" or len(candidates) < 2:
        return candidates, "class" if candidates else ""
    from jaxmotion.scene.instructions import parse_instruction, resolve

    try:
        _, ref = parse_instruction(text)
    except ValueError:  # not in the grammar the parser knows
        return candidates, "class"
    if ref.relation is None:
        return candidates, "class"
    picked = resolve(object_table(room), ref)
    narrowed = [o for o in candidates if o["id"] in picked]
    if not narrowed:  # the parser read another target class than mentioned_objects did
        return candidates, "class"
    return narrowed, "scene graph"


def same_class_others(objects, object_id) -> list[int]:
    """Ids of the objects of ``object_id``'s category other than it: once the target is
    known, the points the ADM's map must leave out (``exclude`` of
    :meth:`jaxmotion.sample.AffordancePipeline.sample_affordance`); ``[]`` when
    ``object_id`` is None or not in ``objects``."""
    cat = next((o["category"] for o in objects if o["id"] == object_id), None)
    if object_id is None or cat is None:
        return []
    return [int(o["id"]) for o in objects if o["category"] == cat and o["id"] != object_id]


def _lit(maps, instance, object_id) -> float:
    """How much ``maps [N,6]`` light up an object: the mean over its points (``instance [N]``
    == ``object_id``) of the strongest channel; −1 when none of its points is there."""
    on = instance == object_id
    return float(maps[on].max(axis=-1).mean()) if on.any() else -1.0


def _find_region(room, text, grounding, spec, *, view=None, adm=None):
    """Step 2 of the module docstring without ``object_id``: ``(centre, chosen object id or
    None, how)``. ``view``: a room-view ADM's ``(view_index, maps)``
    (:func:`_room_view_maps`); else ``adm``: ``(get_pipe, emb, key, sampler, seed)`` (``key``:
    a function returning the key, called only if the ADM is run) for
    :func:`_choose_region`. ``how`` is :attr:`Generation.grounding`."""
    lo, hi = room.xyz[:, :2].min(0), room.xyz[:, :2].max(0)
    candidates, how = candidate_objects(room, text, grounding)
    if view is not None:
        centre, chosen = _region_from_view(room, candidates, *view, spec, lo, hi)
    else:
        get_pipe, emb, key, sampler, seed = adm
        centre, chosen = _choose_region(get_pipe, room, candidates, emb, spec, key, sampler,
                                        seed, lo, hi)
    if len(candidates) > 1:
        how = "adm"
    elif not candidates:
        how = "adm peak"
    return centre, chosen, how


def _choose_region(get_pipe, room, candidates, emb, spec, key, sampler, seed, lo, hi):
    """The crop centre for a text without ``object_id`` (see the module docstring):

    - with ``candidates`` (:func:`candidate_objects`): the ADM is run on a crop centred on
      each and the one whose points it lights up most (mean over its points of the strongest
      channel) wins;
    - otherwise the room is tiled with half-overlapping squares and the tile holding the
      strongest pelvis-affordance peak (mean of its 32 strongest points) wins.
    ``key``: a function returning the ADM's key (called only when the ADM runs).
    Returns ``(centre, chosen object id or None)``.
    """
    if candidates:
        centres = [_object_centre(o, lo, hi, spec.size) for o in candidates]
        if len(candidates) == 1:
            return centres[0], candidates[0]["id"]
        crops = _crops(room, centres, spec, seed, 2)
        maps = _adm_maps(get_pipe, crops, emb, key(), sampler)
        scores = [_lit(a, room.instance[pick], candidates[i]["id"])
                  for (i, pick, *_), a in zip(crops, maps, strict=True)]
        i = crops[int(np.argmax(scores))][0]
        return centres[i], candidates[i]["id"]
    tiles = _centres(lo, hi, spec.size)
    if len(tiles) == 1:
        return tiles[0], None
    crops = _crops(room, tiles, spec, seed, 3)
    maps = _adm_maps(get_pipe, crops, emb, key(), sampler)
    scores = [float(np.sort(a[:, 0])[-32:].mean()) for a in maps]
    return np.asarray(tiles[crops[int(np.argmax(scores))][0]]), None


def _room_view_maps(room, adm_cfg, emb, key, sampler, k: int, seed: int, aot_dir, fingerprint,
                    get_pipe):
    """A room-view ADM's maps for ``k`` samples: ``(view_index [M] into the scene's points,
    maps [K,M,6])``.

    The view is the ADM's training square (``crop.size``, no rotation) centred on the room; a
    room wider than it is tiled with half-overlapping squares (:func:`_centres`) and the
    tiles' points are concatenated."""
    import jax

    from jaxmotion.config import config_from_dict
    from jaxmotion.data.config import CropConfig
    from jaxmotion.data.crop import CropSpec

    view_spec = CropSpec(**{**config_from_dict(CropConfig, adm_cfg["crop"]).__dict__,
                            "rotate": False})
    lo, hi = room.xyz[:, :2].min(0), room.xyz[:, :2].max(0)
    views = _crops(room, _centres(lo, hi, view_spec.size), view_spec, seed, 4)
    v = len(views)
    pts = np.stack([c[2] for c in views])
    col = np.stack([c[3] for c in views])
    # every sample sees every tile: a batch of K x V
    def rep(x):
        return np.ascontiguousarray(np.repeat(x[None], k, 0).reshape(k * v, *x.shape[1:]))

    args = (np.asarray(jax.random.key_data(key)), rep(pts), rep(col),
            jax.tree.map(lambda a: np.ascontiguousarray(np.broadcast_to(a, (k * v, *a.shape))),
                         emb))

    def build():
        pipe = get_pipe()
        return lambda kd, p, c, e: pipe.sample_affordance(jax.random.wrap_key_data(kd), p, c, e,
                                                          sampler)

    if aot_dir is None:  # sample_affordance is jitted itself: no tracing per call
        maps = build()(*args)
    else:
        maps = _aot_call(aot_dir, "adm_view", fingerprint, build, args)
    maps = np.asarray(jax.device_get(maps))
    return np.concatenate([c[1] for c in views]), maps.reshape(k, v * pts.shape[1], -1)


def _region_from_view(room, candidates, view_index, view_maps, spec, lo, hi):
    """The AMDM's square from a room-view ADM's maps (module docstring, step 2): the candidate
    the mean map lights up most (mean over its view points of the strongest channel), else
    the strongest pelvis affordance. Returns ``(centre, chosen object id or None)``."""
    mean = view_maps.mean(axis=0)  # [M, 6], over samples
    if len(candidates) == 1:
        return _object_centre(candidates[0], lo, hi, spec.size), candidates[0]["id"]
    if candidates:
        inst = room.instance[view_index]
        scores = [_lit(mean, inst, o["id"]) for o in candidates]
        best = candidates[int(np.argmax(scores))]
        return _object_centre(best, lo, hi, spec.size), best["id"]
    peak = room.xyz[view_index[int(np.argmax(mean[:, 0]))]]
    return _clamp_centre(peak[:2], lo, hi, spec.size), None


def summary(res: Generation) -> str:
    """A JSON line describing a result (for the command line)."""
    return json.dumps({"text": res.text, "samples": res.num_samples, "frames": int(res.mask.sum()),
                       "target_id": res.target_id, "grounding": res.grounding,
                       "excluded": list(res.excluded), "adm_candidates": res.adm_candidates,
                       "adm_steps": res.adm_steps,
                       "motion_candidates": res.motion_candidates, "steps": res.steps,
                       "fps": res.fps,
                       "fit_error_cm": [round(float(e) * 100, 2) for e in res.fit_error],
                       "timings_s": {k: round(v, 3) for k, v in res.timings.items()}})
