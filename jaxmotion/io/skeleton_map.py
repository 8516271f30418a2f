"""Automatic joint mapping: which joint of an unknown humanoid skeleton is each SMPL-X joint.

Every studio and dataset names its joints its own way (``LeftUpLeg``, ``thigh_l``,
``UpperLeg_L``, ``Bip01 L Thigh``, ``CC_Base_L_Thigh``, ``J_Bip_L_UpperLeg``, ...). This
module reads a skeleton from its names *and* its shape:

1. **Names** are split into words (``_``, ``.``, ``:``, spaces, camelCase and digits), a side
   marker is taken out (``L``, ``Left``, ``l_``, ``.L``, ``_R``, ``Right``, ...), rig prefixes
   are dropped (``mixamorig``, ``CC_Base``, ``Bip01``, ``DEF``, ...), and the rest is looked
   up in a table of synonyms (:data:`ROLES`: ``UpLeg`` / ``UpperLeg`` / ``Thigh`` / a sided
   ``Hip`` start a leg; ``Hand`` / ``Wrist`` end an arm; ``Spine`` / ``Chest`` / ``Torso``
   are the spine; ...). Helper bones (``twist``, ``roll``, ``share``, ``IK``, end sites) are
   never mapped.
2. **The shape** fixes the rest: a leg is the chain from its first joint down to its deepest
   end (hip, knee, ankle, toe: the order of the joints, whatever their names; a leg ending at
   the ankle takes the ankle's end site as its toe); an arm is the chain from the hand up
   (wrist, elbow, shoulder, and the collar when one more joint hangs between it and the
   spine); the pelvis is the joint named so, else where the two legs meet; the spine joints
   are those between the pelvis and the neck, given to ``spine1..3`` by their height; a joint
   the skeleton has no counterpart for is left to be filled in.
   When the names do not say (``Bone01``, ``Joint_7``, another language), the shape alone
   (:func:`_by_shape`): the pelvis is the highest joint with three long branches, the
   largest of which is the spine (arms and head) and the other two the legs; the head is
   the spine's highest end, the hands where its two other branches split into fingers (or
   end); left is up × forward, forward the way the toes point. Such a mapping's confidence
   is lower.
3. **Checks**: the head above the pelvis, the feet below it, each side's joints on its own
   side, and the toes pointing forward (so that a file whose sides are swapped or mirrored is
   caught). A mapping that fails one is an error that shows it, never a silent wrong body.

:func:`auto_joint_map` returns the index of the file's joint for each SMPL-X joint with a
confidence in [0, 1] (1: every joint found by name and shape, every check passed; each joint
filled in or placed by shape alone lowers it).
"""

from __future__ import annotations

import re

import numpy as np

from jaxmotion.geometry.skeleton import JOINT_NAMES, NUM_JOINTS

__all__ = ["AUX_WORDS", "PREFIX_WORDS", "ROLES", "SIDE_WORDS", "MappingError", "auto_joint_map",
           "parse_joint_name"]

#: Side markers, as words of a name.
SIDE_WORDS = {"l": "l", "left": "l", "lft": "l", "lf": "l", "r": "r", "right": "r", "rt": "r",
              "rgt": "r"}
#: Words of rig prefixes, dropped.
PREFIX_WORDS = {"mixamorig", "cc", "base", "bip", "bip001", "bip01", "biped", "def", "org",
                "mch", "jnt", "joint", "bn", "bone", "b", "j", "sk", "skel", "character",
                "char", "rl", "hik", "mocap", "ik_off"}
#: Words that make a joint a helper bone, never mapped.
AUX_WORDS = {"twist", "roll", "share", "end", "nub", "ik", "fk", "pole", "target", "helper",
             "adjust", "corrective", "offset", "aux", "tip", "dummy", "null", "site"}
#: Name (its words joined, without side and digits) -> role.
ROLES = {
    "pelvis": {"hips", "pelvis", "hip", "cog", "centerofgravity"},
    "spine": {"spine", "chest", "upperchest", "torso", "abdomen", "abdomenupper",
              "abdomenlower", "waist", "back", "spinelower", "spineupper", "spinemid"},
    "neck": {"neck", "neckbase", "necklower", "neckupper", "necktwist"},
    "head": {"head"},
    "thigh": {"upleg", "upperleg", "thigh", "femur", "legupper", "uleg", "hip"},
    "knee": {"leg", "lowerleg", "shin", "calf", "knee", "tibia", "leglower", "lleg", "crus"},
    "ankle": {"foot", "ankle"},
    "toe": {"toe", "toes", "toebase", "ball", "football", "toe0"},
    "collar": {"clavicle", "collar", "collarbone", "clav", "shoulder"},
    "upperarm": {"upperarm", "arm", "humerus", "armupper", "uparm", "shoulder"},
    "forearm": {"forearm", "lowerarm", "elbow", "armlower", "loarm"},
    "hand": {"hand", "wrist"},
}
# fractions of the pelvis -> neck height where SMPL-X's spine1, spine2, spine3 sit (its
# neutral rest skeleton)
_SPINE_AT = (0.2425, 0.5277, 0.6366)
_CAMEL = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+")


class MappingError(ValueError):
    """The skeleton could not be mapped with confidence (the message shows what was found)."""


def parse_joint_name(name: str) -> tuple[str | None, str, bool]:
    """``(side, part, helper)`` of a joint name: side ``"l"``, ``"r"`` or None; ``part`` the
    name's remaining words joined, lower case, without digits; ``helper`` when a word marks
    a helper bone (:data:`AUX_WORDS`)."""
    base = name.rpartition(":")[2]  # a namespace prefix (mixamorig:Hips)
    words = [w.lower() for chunk in re.split(r"[^A-Za-z0-9]+", base) if chunk
             for w in _CAMEL.findall(chunk)]
    side = None
    kept = []
    for i, w in enumerate(words):
        s = SIDE_WORDS.get(w)
        if s is not None and side is None and (len(words) > 1):
            side = s
            continue
        kept.append(w)
    helper = any(w in AUX_WORDS for w in kept)
    kept = [w for w in kept if w not in PREFIX_WORDS and not w.isdigit()]
    return side, "".join(kept), helper


def _roles(part: str) -> set[str]:
    return {role for role, parts in ROLES.items() if part in parts}


class _Tree:
    def __init__(self, names, parents):
        self.names = list(names)
        self.parents = np.asarray(parents, int)
        self.children = [[] for _ in self.names]
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)
        self.depth = np.zeros(len(self.names), int)
        for j in range(len(self.names)):  # parents come first in a BVH
            p = self.parents[j]
            self.depth[j] = 0 if p < 0 else self.depth[p] + 1
        self.height = np.zeros(len(self.names), int)  # longest path down (joints)
        for j in reversed(range(len(self.names))):
            if self.children[j]:
                self.height[j] = 1 + max(self.height[c] for c in self.children[j])

    def ancestors(self, j):
        out = []
        while self.parents[j] >= 0:
            j = self.parents[j]
            out.append(j)
        return out

    def is_ancestor(self, a, j):
        return a in self.ancestors(j)


def auto_joint_map(names, parents, positions, *, where: str = "skeleton"):
    """The SMPL-X joint of an unknown skeleton (module docstring).

    Args:
      names: joint names (End Sites as ``<parent>_End``), parents first.
      parents: ``[J]`` parent index (−1 for the root).
      positions: ``[J, 3]`` the joints' positions in the skeleton's rest pose (its offsets;
        the first frame where the offsets are all zero), file units.
      where: the file, for messages.
    Returns:
      ``(index [22] int (−1: filled in), confidence float, notes list[str])``.
    Raises :class:`MappingError` showing the mapping found when a needed joint is missing or
    a check fails.
    """
    tree = _Tree(names, parents)
    pos = np.asarray(positions, np.float64)
    parsed = [parse_joint_name(n) for n in names]
    end_site = [n.endswith("_End") for n in names]
    helper = [h or e for (_, _, h), e in zip(parsed, end_site)]
    named = [set() if helper[j] else _roles(parsed[j][1]) for j in range(len(names))]
    notes: list[str] = []
    index = np.full(NUM_JOINTS, -1)
    slot = {n: i for i, n in enumerate(JOINT_NAMES)}
    by_shape = 0  # joints placed by the shape alone (their names say nothing)

    def found(role, side=None, under=None):
        hits = [j for j in range(len(names)) if role in named[j]
                and (side is None or parsed[j][0] == side)
                and (under is None or tree.is_ancestor(under, j))]
        return min(hits, key=lambda j: (tree.depth[j], j)) if hits else None

    def down(j):
        """The chain from ``j`` down to its deepest end, helper bones stepped through."""
        chain = [j]
        while True:
            kids = [c for c in tree.children[j] if not end_site[c]]
            if not kids:
                return chain
            real = [c for c in kids if not helper[c]]
            j = max(real or kids, key=lambda c: tree.height[c])
            if not helper[j]:
                chain.append(j)

    def show():
        return {n: names[i] for n, i in zip(JOINT_NAMES, index) if i >= 0}

    # legs: the first joint of each, then down the chain
    thighs = {s: found("thigh", s) for s in "lr"}
    hands = {s: found("hand", s, None) for s in "lr"}
    head = None
    if None in thighs.values() or None in hands.values():
        # the names do not say: the body's shape alone
        shaped = _by_shape(tree, pos, helper, end_site, down)
        if shaped is None:
            raise MappingError(
                f"{where}: neither the names (UpLeg / UpperLeg / Thigh, Hand / Wrist with a "
                "side marker such as L, Left, _l) nor the shape (a joint with two legs "
                f"below it and a spine with two arms and a head above) show a body; the joints "
                f"are {names}")
        thighs, hands, head, _ = shaped
        notes.append("legs, arms and head found by the skeleton's shape (their names say "
                     "nothing)")
        by_shape += 3
    pelvis = found("pelvis")
    if pelvis is None or not all(tree.is_ancestor(pelvis, t) for t in thighs.values()):
        common = [a for a in tree.ancestors(thighs["l"]) if a in tree.ancestors(thighs["r"])]
        if not common:
            raise MappingError(f"{where}: the two legs ({names[thighs['l']]}, "
                               f"{names[thighs['r']]}) do not hang from one joint")
        pelvis = common[0]
        by_shape += 1
    index[slot["pelvis"]] = pelvis
    for s in "lr":
        chain = down(thighs[s])
        if len(chain) < 3:
            raise MappingError(f"{where}: the {'left' if s == 'l' else 'right'} leg "
                               f"{[names[j] for j in chain]} has fewer than three joints "
                               "(hip, knee, ankle)")
        for k, name in enumerate(("hip", "knee", "ankle", "foot")):
            if k < len(chain):
                index[slot[f"{s}_{name}"]] = chain[k]
        if len(chain) < 4:  # the toe: the ankle's end site, if it has one
            ends = [c for c in tree.children[chain[2]] if end_site[c]]
            if ends:
                index[slot[f"{s}_foot"]] = ends[0]
            else:
                raise MappingError(f"{where}: the {'left' if s == 'l' else 'right'} leg ends at "
                                   f"{names[chain[-1]]} with no toe joint or end site")
        if any(named[j] and not named[j] & {"thigh", "knee", "ankle", "toe"}
               for j in chain[:4]):
            notes.append(f"leg {s}: {[names[j] for j in chain[:4]]} placed by the chain's order")

    # head, arms, spine
    head = head if head is not None else found("head", None, pelvis)
    if head is None or None in hands.values():
        what = [w for w, j in (("head", head), ("left hand", hands["l"]),
                               ("right hand", hands["r"])) if j is None]
        raise MappingError(f"{where}: no {', '.join(what)} found by name (Head; Hand / Wrist "
                           f"with a side marker); the joints are {names}")
    index[slot["head"]] = head
    spine_path = [a for a in reversed(tree.ancestors(head)) if tree.is_ancestor(pelvis, a)]
    neck = found("neck", None, pelvis)
    if neck is None or neck not in spine_path:
        # the lowest joint between where the arms branch and the head
        above = [a for a in spine_path if a != pelvis and not helper[a]
                 and not any(tree.is_ancestor(a, h) for h in hands.values())]
        neck = above[0] if above else None
        by_shape += neck is not None
    if neck is not None:
        index[slot["neck"]] = neck
    for s in "lr":
        arm = [hands[s]] + [a for a in tree.ancestors(hands[s]) if not helper[a]]
        on_spine = set(spine_path) | {pelvis, head}
        limb = []
        for a in arm:
            if a in on_spine or a == neck:
                break
            limb.append(a)
        if len(limb) < 3:
            raise MappingError(f"{where}: the {'left' if s == 'l' else 'right'} arm "
                               f"{[names[j] for j in reversed(limb)]} has fewer than three "
                               "joints (shoulder, elbow, wrist) below the spine")
        for k, name in enumerate(("wrist", "elbow", "shoulder")):
            index[slot[f"{s}_{name}"]] = limb[k]
        if len(limb) >= 4:
            index[slot[f"{s}_collar"]] = limb[3]
    spines = [a for a in spine_path if a != pelvis and not helper[a]
              and (neck is None or not tree.is_ancestor(neck, a) and a != neck)]
    if len(spines) <= len(_SPINE_AT):  # in order: spine1, spine2, ...
        picked = list(range(len(spines)))
    else:  # the three whose heights are nearest SMPL-X's, in order
        from itertools import combinations

        upv = pos[neck if neck is not None else head] - pos[pelvis]
        frac = np.array([(pos[a] - pos[pelvis]) @ upv for a in spines]) / max(upv @ upv, 1e-12)
        picked = list(min(combinations(range(len(spines)), len(_SPINE_AT)),
                          key=lambda c: float(np.abs(frac[list(c)] - _SPINE_AT).sum())))
    for k, i in enumerate(picked):
        index[slot[f"spine{k + 1}"]] = spines[i]

    # checks
    confidence = 1.0 - 0.1 * by_shape - 0.02 * int(np.sum(index < 0))
    problems = _check(index, pos, slot)
    if problems:
        raise MappingError(
            f"{where}: the joint mapping found is not a plausible body ({'; '.join(problems)}): "
            f"{show()}. Pass joint_map= a JSON file or dict naming the joint of each SMPL-X "
            "joint")
    for j in range(NUM_JOINTS):
        i = index[j]
        if i >= 0 and not named[i] and not end_site[i] and JOINT_NAMES[j] != "pelvis":
            confidence -= 0.03
    return index, float(np.clip(confidence, 0.0, 1.0)), notes


def _by_shape(tree, pos, helper, end_site, down):
    """``(thighs {side: j}, hands {side: j}, head, pelvis)`` of a skeleton from its shape
    alone, or None: the pelvis is the highest joint with three branches of three or more
    joints; the branch holding the most joints is the spine (arms and head), the other two
    the legs; up runs from the feet to the spine's joints; the head is the spine's highest
    end, the arms its two other long branches; left is up × forward, forward the way the
    toes point."""
    def size(j):
        return 1 + sum(size(c) for c in tree.children[j] if not end_site[c])

    real = [j for j in range(len(tree.names)) if not helper[j]]
    for pelvis in sorted(real, key=lambda j: (tree.depth[j], j)):
        branches = [c for c in tree.children[pelvis] if not end_site[c] and tree.height[c] >= 2]
        if len(branches) >= 3:
            break
    else:
        return None
    branches.sort(key=size, reverse=True)
    spine, legs = branches[0], branches[1:3]
    chains = [down(leg) for leg in legs]
    if min(len(c) for c in chains) < 3:
        return None
    body = [j for j in real if tree.is_ancestor(spine, j) or j == spine]
    up = pos[body].mean(0) - np.mean([pos[c[-1]] for c in chains], axis=0)
    if np.linalg.norm(up) < 1e-9:
        return None
    up /= np.linalg.norm(up)
    ends = [j for j in body
            if not any(not end_site[c] and not helper[c] for c in tree.children[j])]
    head = max(ends, key=lambda j: pos[j] @ up)
    path = [a for a in reversed(tree.ancestors(head)) if tree.is_ancestor(pelvis, a)] + [head]
    def hand(j):  # down the arm to where it splits into fingers, or to its end
        while True:
            kids = [c for c in tree.children[j] if not end_site[c] and not helper[c]]
            if len(kids) != 1:
                return j
            j = kids[0]

    arms = [hand(c) for a in path for c in tree.children[a]
            if c not in path and not end_site[c] and not helper[c] and tree.height[c] >= 2]
    if len(arms) < 2:
        return None
    arms = sorted(arms, key=lambda j: tree.depth[j], reverse=True)[:2]
    toe = np.mean([pos[c[-1]] - pos[c[2]] for c in chains], axis=0)
    forward = toe - (toe @ up) * up
    if np.linalg.norm(forward) < 1e-9:
        return None
    left = np.cross(up, forward / np.linalg.norm(forward))
    thighs = dict(zip("lr", sorted((c[0] for c in chains), key=lambda j: -(pos[j] @ left))))
    hands = dict(zip("lr", sorted(arms, key=lambda j: -(pos[j] @ left))))
    return thighs, hands, head, pelvis


def _check(index, pos, slot) -> list[str]:
    """The geometric checks of a mapping (module docstring); the problems found."""
    p = lambda n: pos[index[slot[n]]]
    problems = []
    up = p("head") - p("pelvis")
    size = float(np.linalg.norm(up))
    if size <= 0:
        return ["the head is at the pelvis"]
    up = up / size
    for s in "lr":
        if (p(f"{s}_ankle") - p("pelvis")) @ up > -0.3 * size:
            problems.append(f"the {'left' if s == 'l' else 'right'} ankle is not below the "
                            "pelvis")
    lateral = p("l_hip") - p("r_hip")
    lateral = lateral - (lateral @ up) * up
    if np.linalg.norm(lateral) < 1e-6 * size:
        return problems + ["the hips are at one place"]
    lateral /= np.linalg.norm(lateral)
    if (p("l_shoulder") - p("r_shoulder")) @ lateral <= 0:
        problems.append("the left shoulder is not on the left hip's side")
    forward = np.cross(lateral, up)  # left = up x forward
    toes = [(p(f"{s}_foot") - p(f"{s}_ankle")) @ forward for s in "lr"]
    if sum(toes) < 0:
        problems.append("the toes point backwards: left and right are swapped (or the file "
                        "is mirrored)")
    return problems
