"""HUMANISE motions (Wang et al., NeurIPS 2022) placed in their ScanNet scenes.

Two layouts are read (the user's own copy; 30 fps, z-up, metres):

- **Original release**: ``ROOT/align_data_release/<action>/<scene>_<id>/anno.pkl``, a list
  of dicts (``action``, ``motion``, ``scene``, ``scene_translation`` [3], ``translation``
  [3], ``rotation`` (z angle, radians), ``utterance``, ``object_id``, ``object_label``,
  ``object_semantic_label``), whose ``motion`` points into
  ``ROOT/pure_motion/<action>/<id>/motion.pkl``, a tuple ``(gender, trans [L,3], orient
  [L,3], betas [16], body_pose [L,63], hand_pose [L,90], jaw_pose [L,3], eye_pose [L,6],
  joints [L,127,3])``. The motion is placed in the scene by
  ``translate(translation) · rot_z(rotation) · translate(−p)``, ``p`` = the pelvis xy
  (z = 0) at the anchor frame (the first for ``stand up``, else the last;
  :func:`jaxmotion.data.anchor_frame`), taken from the file's ``joints`` (its own SMPL-X
  model), applied to the SMPL-X parameters. ``pure_motion`` files alone read unplaced.
- **Re-formatted release**: ``ROOT/motions/NNNNNN.pkl`` = ``(array [L, 159] = trans 3 +
  orient 3 + body 63 + hands 90, betas [10])`` and ``ROOT/annotation.csv`` (``motion_id,
  scene_id, scene_trans_x/y/z, object_id, object_label, object_semantic_label, action,
  text``). Its motions are taken as already placed (the table has no placement columns).

In both, the motion lives in HUMANISE's scene frame: the ScanNet scan moved by
``scene_translation`` (``info["scene_translation"]``). Joints are the forward kinematics
of the (placed) parameters on jaxmotion's SMPL-X skeleton (see :mod:`jaxmotion.io.amass`;
a few cm from HUMANISE's gendered models); hands, jaw and eyes are dropped.

**Pickles run code when loaded.** Read only your own copy of the dataset: these files are
unpickled with a restricted loader that accepts only NumPy arrays and Python containers
(``trust_pickle=True`` lifts the restriction for a file you trust that needs more).
"""

from __future__ import annotations

import csv
import io
import pickle
from pathlib import Path

import numpy as np

from jaxmotion.constants import SCENE_FPS
from jaxmotion.data.format import anchor_frame
from jaxmotion.geometry.skeleton import NUM_BETAS, NUM_JOINTS, rest_joints_host
from jaxmotion.io.motion import Motion, MotionFormatError, smplx_joints_host

__all__ = ["load_humanise", "read_pickle"]

_ALLOWED = {
    ("numpy", "ndarray"), ("numpy", "dtype"), ("_codecs", "encode"),
    ("collections", "OrderedDict"),
    *((f"numpy{m}.multiarray", n) for m in (".core", "._core") for n in ("_reconstruct", "scalar")),
    *((f"numpy{m}.numeric", "_frombuffer") for m in (".core", "._core")),
}


class _NumpyOnly(pickle.Unpickler):
    def find_class(self, module, name):
        if (module, name) not in _ALLOWED:
            raise MotionFormatError(
                f"the pickle wants to load {module}.{name}; only NumPy arrays are accepted "
                "(pass trust_pickle=True if this is your own dataset copy and you trust it)")
        return super().find_class(module, name)


def read_pickle(path, *, trust_pickle: bool = False):
    """Unpickle a HUMANISE file: NumPy arrays and containers only unless ``trust_pickle``."""
    path = Path(path)
    if not path.is_file():
        raise MotionFormatError(f"{path}: no such file")
    try:
        raw = path.read_bytes()
        return pickle.loads(raw) if trust_pickle else _NumpyOnly(io.BytesIO(raw)).load()
    except MotionFormatError as e:
        raise MotionFormatError(f"{path}: {e}") from None
    except Exception as e:  # any unpickling failure means a malformed file
        raise MotionFormatError(f"{path}: not a readable pickle ({type(e).__name__}: {e}); give "
                                "a HUMANISE .pkl file") from e


def _rows(x, width: int, name: str, where: str, n: int | None = None) -> np.ndarray:
    try:
        a = np.asarray(x, np.float64)
    except (TypeError, ValueError):
        a = np.zeros((0,))
    if a.ndim != 2 or a.shape[1] != width or (n is not None and a.shape[0] != n) or not len(a):
        raise MotionFormatError(f"{where}: {name} must be a [{n or 'L'}, {width}] number array, "
                                f"got {getattr(x, 'shape', type(x).__name__)}")
    if not np.isfinite(a).all():
        raise MotionFormatError(f"{where}: {name} has NaN or inf values")
    return a


def _betas(x, where: str) -> np.ndarray:
    try:
        b = np.asarray(x, np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise MotionFormatError(f"{where}: betas must be a number array, got "
                                f"{type(x).__name__}") from None
    if not np.isfinite(b).all():
        raise MotionFormatError(f"{where}: betas has NaN or inf values")
    return np.pad(b[:NUM_BETAS], (0, max(0, NUM_BETAS - len(b))))


def _pure_motion(path: Path, trust: bool):
    """(trans, orient, body [L,21,3], betas [10], file joints or None, gender)."""
    where = str(path)
    m = read_pickle(path, trust_pickle=trust)
    if not isinstance(m, (tuple, list)) or len(m) < 5:
        raise MotionFormatError(f"{where}: a HUMANISE motion.pkl is a tuple (gender, trans, "
                                f"orient, betas, body_pose, ...), got {type(m).__name__}")
    trans = _rows(m[1], 3, "trans", where)
    n = len(trans)
    orient = _rows(m[2], 3, "orient", where, n)
    body = _rows(m[4], 63, "body_pose", where, n).reshape(n, NUM_JOINTS - 1, 3)
    joints = None
    if len(m) >= 9 and np.ndim(m[8]) == 3 and np.shape(m[8])[0] == n and np.shape(m[8])[2] == 3:
        joints = np.asarray(m[8], np.float64)
    gender = m[0].decode() if isinstance(m[0], bytes) else str(m[0])
    return trans, orient, body, _betas(m[3], where), joints, gender


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _placed(trans, orient, betas, rotation: float, translation, pelvis_xy):
    """SMPL-X parameters moved by translate(t) · rot_z(a) · translate(−(p_x, p_y, 0))."""
    from scipy.spatial.transform import Rotation

    r = _rot_z(rotation)
    j0 = rest_joints_host(betas)[0]  # the pelvis turns about its rest position
    p = np.array([pelvis_xy[0], pelvis_xy[1], 0.0])
    new_trans = (j0 + trans - p) @ r.T + np.asarray(translation, np.float64) - j0
    new_orient = (Rotation.from_matrix(r) * Rotation.from_rotvec(orient)).as_rotvec()
    return new_trans, new_orient


def _anno_motion(path: Path, index: int, trust: bool) -> Motion:
    where = str(path)
    annos = read_pickle(path, trust_pickle=trust)
    if isinstance(annos, dict):
        annos = [annos]
    if not isinstance(annos, list) or not annos or not all(isinstance(a, dict) for a in annos):
        raise MotionFormatError(f"{where}: a HUMANISE anno.pkl is a list of dicts")
    if not -len(annos) <= index < len(annos):
        raise MotionFormatError(f"{where}: index={index} but the file has {len(annos)} "
                                f"annotations (0 .. {len(annos) - 1})")
    a = annos[index]
    need = ("action", "motion", "translation", "rotation")
    if missing := [k for k in need if k not in a]:
        raise MotionFormatError(f"{where}: annotation {index} lacks {missing}")
    root = path.parents[3] if len(path.parents) > 3 else path.parent
    rel = Path(str(a["motion"]).replace("\\", "/"))
    parts = rel.parts[rel.parts.index("pure_motion"):] if "pure_motion" in rel.parts else rel.parts
    file = root.joinpath(*parts)
    if not file.is_file():
        raise MotionFormatError(f"{where}: annotation {index} points to {a['motion']!r}, looked "
                                f"for {file}; keep pure_motion/ next to align_data_release/")
    trans, orient, body, betas, joints, gender = _pure_motion(file, trust)
    action = str(a["action"]).strip().replace(" ", "_")
    k = anchor_frame(action, np.ones(len(trans), bool))
    pelvis = joints[k, 0] if joints is not None else smplx_joints_host(
        orient[k:k + 1], body[k:k + 1], trans[k:k + 1], betas)[0, 0]
    try:
        rotation = float(np.asarray(a["rotation"]).reshape(-1)[0])
        translation = np.asarray(a["translation"], np.float64).reshape(3)
    except (TypeError, ValueError, IndexError) as e:
        raise MotionFormatError(f"{where}: annotation {index} has a bad rotation / translation "
                                f"({e}); rotation is a z angle, translation 3 numbers") from e
    trans, orient = _placed(trans, orient, betas, rotation, translation, pelvis[:2])
    info = {"format": "humanise", "action": action, "gender": gender, "index": index,
            "motion_file": str(file)}
    for key in ("scene", "object_id", "object_label", "object_semantic_label"):
        if key in a:
            v = a[key]
            info[key] = v.item() if isinstance(v, np.generic) else (
                v.tolist() if isinstance(v, np.ndarray) else v)
    if "scene_translation" in a:
        info["scene_translation"] = np.asarray(a["scene_translation"], float).reshape(3).tolist()
    text = str(a.get("utterance", "")).strip()
    return Motion(joints=smplx_joints_host(orient, body, trans, betas), fps=SCENE_FPS,
                  global_orient=orient, body_pose=body, transl=trans, betas=betas,
                  texts=(text,) if text else (), source=f"{where}#{index}", info=info)


def _annotation_row(csv_path: Path, motion_id: str) -> dict | None:
    if not csv_path.is_file():
        return None
    try:
        with open(csv_path, newline="", encoding="utf-8") as f:
            for row in csv.DictReader(f):
                mid = str(row.get("motion_id", "")).strip()
                if mid == motion_id or (mid.isdigit() and motion_id.isdigit()
                                        and int(mid) == int(motion_id)):
                    return row
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise MotionFormatError(f"{csv_path}: unreadable annotation table ({e})") from e
    return None


def _reformatted_motion(path: Path, trust: bool) -> Motion:
    where = str(path)
    m = read_pickle(path, trust_pickle=trust)
    if not isinstance(m, (tuple, list)) or len(m) != 2:
        raise MotionFormatError(f"{where}: a re-formatted HUMANISE motion is a tuple (array "
                                f"[L, 159], betas [10]), got {type(m).__name__}")
    arr = _rows(m[0], 159, "the motion array", where)
    n = len(arr)
    trans, orient, body = arr[:, :3], arr[:, 3:6], arr[:, 6:69].reshape(n, NUM_JOINTS - 1, 3)
    betas = _betas(m[1], where)
    info: dict = {"format": "humanise", "motion_id": path.stem}
    texts: tuple[str, ...] = ()
    row = _annotation_row(path.parent.parent / "annotation.csv", path.stem)
    if row is not None:
        try:
            info["scene_translation"] = [float(row[f"scene_trans_{c}"]) for c in "xyz"]
        except (KeyError, TypeError, ValueError):
            pass
        for key in ("scene_id", "object_id", "object_label", "object_semantic_label", "action"):
            if row.get(key) not in (None, ""):
                info[key] = row[key].strip()
        if "action" in info:
            info["action"] = info["action"].replace(" ", "_")
        if (text := (row.get("text") or "").strip()):
            texts = (text,)
    return Motion(joints=smplx_joints_host(orient, body, trans, betas), fps=SCENE_FPS,
                  global_orient=orient, body_pose=body, transl=trans, betas=betas,
                  texts=texts, source=where, info=info)


def load_humanise(path, *, index: int = 0, fps: float | None = None,
                  trust_pickle: bool = False) -> Motion:
    """Read one HUMANISE motion; see the module docstring for the layouts and placement.

    Args:
      path: ``align_data_release/<action>/<scene>_<id>/anno.pkl`` (placed, with its
        utterance), ``pure_motion/<action>/<id>/motion.pkl`` (unplaced, no text) or
        ``motions/NNNNNN.pkl`` of the re-formatted release (text and scene from
        ``annotation.csv`` next to ``motions/``).
      index: which annotation of an ``anno.pkl`` (default the first).
      fps: resample to this rate (default HUMANISE's 30 fps).
      trust_pickle: allow any Python object in the pickle (runs its code; see above).
    Returns:
      joints and SMPL-X body parameters (metres, z-up, scene frame); ``texts`` the
      instruction; ``info`` the scene id, action, object id / label, scene_translation.
    """
    path = Path(path)
    if path.name == "anno.pkl":
        motion = _anno_motion(path, int(index), trust_pickle)
    elif path.parent.name == "motions":
        motion = _reformatted_motion(path, trust_pickle)
    else:
        trans, orient, body, betas, _, gender = _pure_motion(path, trust_pickle)
        motion = Motion(joints=smplx_joints_host(orient, body, trans, betas), fps=SCENE_FPS,
                        global_orient=orient, body_pose=body, transl=trans, betas=betas,
                        source=str(path), info={"format": "humanise", "gender": gender,
                                                "placed": False})
    return motion if fps is None else motion.resampled(fps)
