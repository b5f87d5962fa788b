"""Skeleton matching: a source skeleton's joints found for the roles a retarget map needs.

A retarget map (:mod:`rigmap.map.joint_map`) names, per rig joint, the source joint
that drives it; written by hand it fits one naming only. Here the source joints are
found for anatomical roles (``hips``, ``spine``, ``chest``, ``neck``, ``head``, and per
side ``upper_arm``, ``forearm``, ``hand``, ``fingers``, ``thigh``, ``shin``, ``foot``,
``ball``, ``toe_end``) from the BVH hierarchy and rest pose:

- topology: zero-length helper joints (CMU's ``LHipJoint``, ``lowerback``, collars) and
  twist/roll joints fold into their parent; the hips are the first joint with three
  branches; the two whose tips point the same way are the legs, the one against them
  the spine; the spine's first branching joint is the chest, its most upward branch the
  neck and the other two the arms; along a limb the two longest consecutive bones are the upper
  and lower limb (so a clavicle or a hip helper with length is skipped);
- the rest pose: up from the spine against the legs, forward from the feet to the toes,
  left = up × forward, so left and right come from geometry;
- names: the common conventions (both CMU BVH conversions, Mixamo ``mixamorig:``,
  MotionBuilder/HumanIK ``LeftUpLeg``, Rokoko, 3ds Max ``Bip01 L Thigh``, ``l_hip``,
  ``L_Thigh``, ``thigh.L``) confirm each joint's role and side, break ties where the
  topology cannot (the head along a neck chain, the middle finger), and a name that
  contradicts the topology makes the match unsure.

A rig's ``roles`` table (``map.rigs.<rig>.roles`` in ``conf/map/default.yaml``) turns
the matched roles into a retarget map in the shipped YAML form. All rules and
thresholds here are ours (the paper gives no retargeting details, §6.3).
"""

from __future__ import annotations

import itertools
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from rigmap.map.joint_map import JointMap, JointMapError
from rigmap.store import write_text_atomic

SIDES = ("l", "r")
CENTRE_ROLES = ("hips", "spine", "chest", "neck", "head", "head_end")
LIMB_ROLES = ("upper_arm", "forearm", "hand", "fingers", "thigh", "shin", "foot", "ball", "toe_end")
ROLES = CENTRE_ROLES + tuple(f"{r}_{s}" for s in SIDES for r in LIMB_ROLES)
# roles a source may lack (the rig joint is then learned from the corpus, as fingers are)
OPTIONAL_ROLES = frozenset(
    ["spine", "head_end"] + [f"{r}_{s}" for s in SIDES for r in ("fingers", "ball", "toe_end")]
)
HELPER_FRACTION = 1e-4  # a bone this much shorter than the longest is a helper (ours)
TWIST = re.compile(r"twist|roll", re.IGNORECASE)  # twist/roll helpers: folded too (ours)
SAME_WAY_COSINE = 0.5  # legs: their tips point within 60° of each other (ours)

# Name patterns: (regex on the lower-case name with separators and the side removed,
# roles it can name). First match wins, so compound words come before their parts.
NAME_PATTERNS: tuple[tuple[str, frozenset[str]], ...] = tuple(
    (pattern, frozenset(roles.split()))
    for pattern, roles in (
        (r"(end|nub|tip|top|site)$", "head_end toe_end fingers"),
        (r"thumb", "thumb"),
        (r"index|middle|ring|pinky|little|finger", "fingers"),
        (r"forearm|lowerarm|elbow|radius", "forearm"),
        (r"upperarm|humerus", "upper_arm"),
        (r"clavicle|collar", "clavicle"),
        (r"shoulder", "upper_arm clavicle"),
        (r"arm", "upper_arm"),
        (r"hand|wrist", "hand"),
        (r"upleg|upperleg|thigh|femur", "thigh"),
        (r"hipjoint", "helper"),
        (r"lowerleg|shin|calf|knee|tibia|leg", "shin"),
        (r"toe|ball", "ball"),
        (r"foot|ankle", "foot"),
        (r"hips|pelvis|root", "hips"),
        (r"hip", "thigh hips"),
        (r"neck", "neck"),
        (r"head", "head"),
        (r"spine", "spine chest hips"),  # 3ds Max Biped hangs the legs on its first spine joint
        (r"chest|back|torso|abdomen", "spine chest"),
    )
)
SIDE_WORDS = {"l": ("left", "l", "lft"), "r": ("right", "r", "rgt", "rt")}
NAMESPACE = re.compile(r"^.*[:|]|^(mixamorig\d*|character\d*|bip\d*)[_ ]?", re.IGNORECASE)
PART_START = re.compile(
    r"hip|hand|finger|thumb|foot|toe|femur|tibia|humerus|radius|wrist|"
    r"clavicle|collar|shoulder|elbow|knee|ankle|arm|leg|up|thigh|shin"
)
AXIS_LABELS = ("x", "y", "z")


class SkeletonMatchError(JointMapError):
    """A skeleton whose joints could not all be matched; names them and the draft map."""


@dataclass(frozen=True)
class Skeleton:
    """A source hierarchy: joint (and end-site) names, parents (``-1``: root), rest world
    positions (every channel zero), in the source's own axes and unit."""

    names: tuple[str, ...]
    parents: np.ndarray
    rest: np.ndarray

    @classmethod
    def from_bvh(cls, motion) -> Skeleton:
        """Joints then end sites (``<parent>_end``), as :func:`tracks_from_bvh` names them."""
        n = motion.n_joints
        rest = np.zeros((n + len(motion.end_site_parents), 3))
        for j in range(n):
            parent = motion.parents[j]
            rest[j] = motion.offsets[j] + (rest[parent] if parent >= 0 else 0.0)
        for k, parent in enumerate(motion.end_site_parents):
            rest[n + k] = rest[parent] + motion.end_site_offsets[k]
        parents = np.concatenate([motion.parents, motion.end_site_parents]).astype(int)
        return cls((*motion.joint_names, *motion.end_site_names), parents, rest)


@dataclass
class Match:
    """The roles found (role → source joint), the source axes and what is unsure."""

    roles: dict[str, str] = field(default_factory=dict)
    up: str = ""
    forward: str = ""
    left: str = ""
    height: float = 0.0
    problems: list[str] = field(default_factory=list)
    by_name: int = 0


# --------------------------------------------------------------------------- names
def name_side_and_roles(name: str) -> tuple[str | None, frozenset[str]]:
    """The side (``l``, ``r`` or ``None``) and the roles a joint name can stand for."""
    bare = NAMESPACE.sub("", name)
    spaced = re.sub(r"([a-z0-9])([A-Z])|([A-Z])([A-Z][a-z])", r"\1\3 \2\4", bare)
    tokens = [t for t in re.split(r"[\s_.\-]+", spaced.lower()) if t]
    side = None
    for candidate, words in SIDE_WORDS.items():
        hits = [k for k, t in enumerate(tokens) if t in words]
        if hits and side is None and (len(tokens) > 1):
            side = candidate
            del tokens[hits[0]]
    word = "".join(tokens)
    if side is None and word[:1] in ("l", "r") and PART_START.match(word[1:]):
        side, word = word[0], word[1:]  # CMU's lhand, LHipJoint, lfemur
    return side, _roles_of(word)


def _roles_of(word: str) -> frozenset[str]:
    for pattern, roles in NAME_PATTERNS:
        if re.search(pattern, word):
            return roles
    return frozenset()


# --------------------------------------------------------------------------- topology
class _Tree:
    """The hierarchy with zero-length helpers folded into their parents."""

    def __init__(self, skeleton: Skeleton):
        self.skeleton = skeleton
        rest, parents = skeleton.rest, skeleton.parents
        lengths = np.array(
            [np.linalg.norm(rest[j] - rest[p]) if p >= 0 else 0.0 for j, p in enumerate(parents)]
        )
        floor = HELPER_FRACTION * max(float(lengths.max()), 1e-300)
        node = np.arange(len(parents))
        for j, p in enumerate(parents):  # parents come before their children
            if p >= 0 and (lengths[j] <= floor or TWIST.search(skeleton.names[j])):
                node[j] = node[p]
        self.children: dict[int, list[int]] = {int(j): [] for j in set(node.tolist())}
        for j, p in enumerate(parents):
            if p >= 0 and node[j] == j:
                self.children[int(node[p])].append(j)
        self.root = int(node[int(np.flatnonzero(parents < 0)[0])])
        self._heights: dict[int, int] | None = None

    def name(self, j: int) -> str:
        return self.skeleton.names[j]

    def vector(self, a: int, b: int) -> np.ndarray:
        return self.skeleton.rest[b] - self.skeleton.rest[a]

    def leaves(self, j: int) -> list[int]:
        """The leaves under ``j``, children in order (a stack: a chain of any depth)."""
        out, stack = [], [j]
        while stack:
            k = stack.pop()
            kids = self.children[k]
            if kids:
                stack.extend(reversed(kids))
            else:
                out.append(k)
        return out

    def reach(self, origin: int, j: int) -> np.ndarray:
        """From ``origin`` to the farthest rest-pose leaf under ``j``."""
        vectors = [self.vector(origin, leaf) for leaf in self.leaves(j)]
        return max(vectors, key=lambda v: float(np.linalg.norm(v)))

    def height(self, j: int) -> int:
        """Joints on the longest way from ``j`` down to a leaf (found once for every joint)."""
        if self._heights is None:
            self._heights = {}
            for k in reversed(self._order()):  # children before their parents
                kids = self.children[k]
                self._heights[k] = 0 if not kids else 1 + max(self._heights[c] for c in kids)
        return self._heights[j]

    def _order(self) -> list[int]:
        """Every folded joint, each parent before its children."""
        out, stack = [], [self.root]
        while stack:
            k = stack.pop()
            out.append(k)
            stack.extend(self.children[k])
        return out

    def path(self, j: int, *, stop_at_branch: bool) -> list[int]:
        """From ``j`` down the deepest child, to a leaf (or to the first branching joint)."""
        out = [j]
        while self.children[out[-1]]:
            kids = self.children[out[-1]]
            if stop_at_branch and len(kids) > 1:
                break
            out.append(max(kids, key=self.height))
        return out


def _unit(vector: np.ndarray) -> np.ndarray:
    norm = float(np.linalg.norm(vector))
    return vector / norm if norm > 0 else vector


def _snap(vector: np.ndarray, exclude: tuple[int, ...] = ()) -> tuple[int, float]:
    """The source axis (index, sign) closest to ``vector``, not one of ``exclude``."""
    scores = np.abs(vector).astype(float)
    scores[list(exclude)] = -1.0
    axis = int(np.argmax(scores))
    return axis, 1.0 if vector[axis] >= 0 else -1.0


def _axis_label(axis: int, sign: float) -> str:
    return f"{'+' if sign > 0 else '-'}{AXIS_LABELS[axis]}"


def _limb(tree: _Tree, start: int) -> list[int]:
    """A limb's chain from its upper joint: the two longest consecutive bones begin it
    (so a clavicle or hip helper before them, and fingers or toes after, are skipped)."""
    chain = tree.path(start, stop_at_branch=False)
    if len(chain) < 3:
        return []
    bones = [float(np.linalg.norm(tree.vector(a, b))) for a, b in itertools.pairwise(chain)]
    first = max(range(len(bones) - 1), key=lambda i: bones[i] + bones[i + 1])
    return chain[first:]


def _pick_pair(tree: _Tree, origin: int, kids: list[int]) -> tuple[int, int] | None:
    """The two branches whose tips point most the same way, at most alike distances."""
    best, best_score = None, SAME_WAY_COSINE
    for i, a in enumerate(kids):
        for b in kids[i + 1 :]:
            ra, rb = tree.reach(origin, a), tree.reach(origin, b)
            la, lb = float(np.linalg.norm(ra)), float(np.linalg.norm(rb))
            score = float(_unit(ra) @ _unit(rb)) - abs(la - lb) / max(la, lb, 1e-300)
            if score > best_score:
                best, best_score = (a, b), score
    return best


# --------------------------------------------------------------------------- matching
def match_skeleton(skeleton: Skeleton) -> Match:
    """Roles, axes and height of ``skeleton``; what could not be decided is in ``problems``."""
    tree, match = _Tree(skeleton), Match()
    found: dict[str, int] = {}
    hips = tree.root
    while len(tree.children[hips]) == 1:
        hips = tree.children[hips][0]
    body = _body(tree, hips, match.problems)
    if body is not None:
        legs, spine, up = body
        found["hips"] = hips
        arms = _torso(tree, spine, up, found, match.problems)
        left = _left_axis(tree, legs, up, match)
        if left is not None:
            _limbs(tree, "leg", hips, legs, left, found, match.problems)
            _limbs(tree, "arm", found.get("chest", hips), arms, left, found, match.problems)
        match.height = float(np.ptp(skeleton.rest @ up))
    for role in ROLES:  # in role order, for a stable report
        if role in found:
            match.roles[role] = tree.name(found[role])
    _check_names(match)
    return match


def _body(tree: _Tree, hips: int, problems: list[str]):
    """The legs (two branches of the hips pointing the same way), the spine (the branch
    most against them) and the up vector (spine against legs), or ``None``."""
    kids = tree.children[hips]
    pair = _pick_pair(tree, hips, kids) if len(kids) >= 3 else None
    if pair is None:
        problems.append(
            f"no joint branches into two alike legs and a spine (the first branching "
            f"joint is {tree.name(hips)!r}, with {len(kids)} branches)"
        )
        return None
    down = _unit(_unit(tree.reach(hips, pair[0])) + _unit(tree.reach(hips, pair[1])))
    others = [k for k in kids if k not in pair]
    spine = min(others, key=lambda k: float(_unit(tree.reach(hips, k)) @ down))
    if float(_unit(tree.reach(hips, spine)) @ down) >= 0:
        problems.append(f"no branch of {tree.name(hips)!r} points away from its legs (no spine)")
        return None
    axis, sign = _snap(_unit(tree.vector(hips, spine)) - down)
    up = np.zeros(3)
    up[axis] = sign
    return pair, spine, up


def _torso(tree: _Tree, spine: int, up, found: dict, problems: list[str]) -> list[int]:
    """Spine, chest, neck, head (and its tip) found; returns the two arm branches."""
    column = tree.path(spine, stop_at_branch=True)
    chest = column[-1]
    kids = tree.children[chest]
    if len(kids) < 2:
        problems.append(f"the spine ends at {tree.name(chest)!r} with no branch for the arms")
        return []
    found["chest"] = chest
    if len(column) >= 2:
        found["spine"] = column[-2]
    neck = max(kids, key=lambda k: float(_unit(tree.reach(chest, k)) @ up))
    arms = [k for k in kids if k != neck]
    if len(arms) > 2:  # keep the two that reach farthest (more: props, breasts)
        arms = sorted(arms, key=lambda k: -float(np.linalg.norm(tree.reach(chest, k))))[:2]
    chain = tree.path(neck, stop_at_branch=False)
    named = [i for i, j in enumerate(chain) if name_side_and_roles(tree.name(j))[1] == {"head"}]
    head = named[0] if named else max(0, len(chain) - 2)
    found["head"] = chain[head]
    if head > 0:
        found["neck"] = chain[0]
    if head + 1 < len(chain):
        found["head_end"] = chain[head + 1]
    return arms


def _left_axis(tree: _Tree, legs, up, match: Match) -> np.ndarray | None:
    """The character's left: up × forward, forward from the feet to the toes in the rest
    pose; from the legs' side names when the feet have no toes."""
    up_axis = int(np.flatnonzero(up)[0])
    toes = np.zeros(3)
    for leg in legs:
        chain = _limb(tree, leg)
        if len(chain) > 3:
            toes += tree.vector(chain[2], chain[-1])
    toes -= (toes @ up) * up
    if float(np.linalg.norm(toes)) > 0:
        axis, sign = _snap(toes, exclude=(up_axis,))
        forward = np.zeros(3)
        forward[axis] = sign
        left = np.cross(up, forward)
    else:
        sides = [name_side_and_roles(tree.name(leg))[0] for leg in legs]
        if set(sides) != {"l", "r"}:
            match.problems.append(
                "cannot tell left from right: the feet have no toes and the legs' names no side"
            )
            return None
        lateral = tree.vector(legs[sides.index("r")], legs[sides.index("l")])
        axis, sign = _snap(lateral - (lateral @ up) * up, exclude=(up_axis,))
        left = np.zeros(3)
        left[axis] = sign
        forward = np.cross(left, up)
    match.up, match.forward, match.left = (_axis_label(*_snap(v)) for v in (up, forward, left))
    return left


def _limbs(tree: _Tree, kind: str, origin: int, pair, left, found: dict, problems: list) -> None:
    """A pair of limbs (or the one found): side from the rest pose, roles along the chain."""
    if len(pair) != 2:
        problems.append(
            f"{tree.name(origin)!r} has {len(pair)} {kind} branch(es) where two are expected"
        )
    roles = (
        ("thigh", "shin", "foot", "ball", "toe_end")
        if kind == "leg"
        else ("upper_arm", "forearm", "hand")
    )
    sides = {}
    for start in pair:
        centre = tree.skeleton.rest[tree.leaves(start)].mean(axis=0) - tree.skeleton.rest[origin]
        side = "l" if float(centre @ left) > 0 else "r"
        if side in sides:
            problems.append(f"both {kind}s are on the {'left' if side == 'l' else 'right'}")
            return
        sides[side] = start
    for side, start in sides.items():
        chain = _limb(tree, start)
        if not chain:
            problems.append(f"the {kind} from {tree.name(start)!r} has fewer than 3 joints")
            continue
        for role, joint in zip(roles, chain, strict=False):
            found[f"{role}_{side}"] = joint
        if kind == "arm" and len(chain) >= 3:
            finger = _finger(tree, chain[1], chain[2])
            if finger is not None:
                found[f"fingers_{side}"] = finger


def _finger(tree: _Tree, forearm: int, hand: int) -> int | None:
    """The hand's child for the middle finger: named so, else the one that goes on most
    straight from the forearm (never a thumb)."""
    kids = [k for k in tree.children[hand] if "thumb" not in name_side_and_roles(tree.name(k))[1]]
    if not kids:
        return None
    middle = [k for k in kids if "middle" in tree.name(k).lower()]
    if middle:
        return middle[0]
    along = _unit(tree.vector(forearm, hand))
    return max(kids, key=lambda k: float(_unit(tree.vector(hand, k)) @ along))


def _check_names(match: Match) -> None:
    """Each matched joint's name must not say another role or the other side."""
    for role, joint in match.roles.items():
        side, roles = name_side_and_roles(joint)
        base, _, role_side = role.rpartition("_")
        if role_side not in SIDES:
            base, role_side = role, None
        if roles and base not in roles:
            match.problems.append(
                f"{role} is {joint!r} by the skeleton's shape, but its name "
                f"says {'/'.join(sorted(roles))}"
            )
        elif role_side and side and side != role_side:
            match.problems.append(
                f"{role} is {joint!r} by the rest pose, but its name says "
                f"the {'left' if side == 'l' else 'right'} side"
            )
        elif roles:
            match.by_name += 1


# --------------------------------------------------------------------------- frames
@dataclass(frozen=True)
class FrameCheck:
    """Frames that are not captured motion: an added T-pose at frame 0 (excluded from the
    mapping) and glitch frames whose every channel is zero (rebuilt from their neighbours)."""

    tpose_at_0: bool
    glitches: tuple[int, ...]

    def describe(self) -> str:
        parts = ["frame 0 is a T-pose (excluded)" if self.tpose_at_0 else "no T-pose frame"]
        if self.glitches:
            parts.append(
                f"glitch frames (every channel zero) {list(self.glitches)} repaired "
                "from their neighbours"
            )
        else:
            parts.append("no glitch frames")
        return ", ".join(parts)

    def apply(self, positions: np.ndarray) -> np.ndarray:
        """``positions`` ``(F, J, 3)`` with glitch frames interpolated and the T-pose cut."""
        out = np.array(positions, dtype=np.float64)
        bad = np.zeros(len(out), dtype=bool)
        bad[list(self.glitches)] = True
        if self.tpose_at_0:
            bad[0] = True
        good = np.flatnonzero(~bad)
        if len(good) == 0:
            raise JointMapError("every frame is a glitch (all channels zero) or a T-pose")
        frames = np.arange(len(out))
        flat = out.reshape(len(out), -1)
        for column in range(flat.shape[1]):
            flat[bad, column] = np.interp(frames[bad], good, flat[good, column])
        return flat.reshape(out.shape)[1:] if self.tpose_at_0 else flat.reshape(out.shape)


TPOSE_ARM_DEGREES = 25.0  # T-pose: both arms within this of horizontal (ours)
TPOSE_JUMP = 5.0  # ... and frame 0 this many median frame steps from the next good frame (ours)


def check_frames(values: np.ndarray, positions: np.ndarray, names, match: Match) -> FrameCheck:
    """Glitch frames from the raw channel ``values``; a T-pose at frame 0 from the joint
    ``positions`` (``names`` order): arms level, and a jump to the next good frame."""
    glitches = tuple(int(f) for f in np.flatnonzero((np.asarray(values) == 0).all(axis=1)))
    good = [f for f in range(len(positions)) if f not in glitches]
    arms = [(match.roles.get(f"upper_arm_{s}"), match.roles.get(f"hand_{s}")) for s in SIDES]
    if len(good) < 3 or good[0] != 0 or not match.up or not all(a and b for a, b in arms):
        return FrameCheck(False, glitches)
    up = np.zeros(3)
    axis = AXIS_LABELS.index(match.up[1])
    up[axis] = 1.0
    index = {n: k for k, n in enumerate(names)}
    level = all(
        abs(float(_unit(positions[0, index[b]] - positions[0, index[a]]) @ up))
        < np.sin(np.radians(TPOSE_ARM_DEGREES))
        for a, b in arms
    )
    steps = np.linalg.norm(np.diff(positions[good], axis=0), axis=2).max(axis=1)
    jump = bool(steps[0] > TPOSE_JUMP * float(np.median(steps[1:])))
    return FrameCheck(bool(level and jump), glitches)


# --------------------------------------------------------------------------- maps
UNKNOWN = "???"  # a draft map's value for a rig joint whose source joint was not found
HUMAN_HEIGHT_CM = (120.0, 230.0)  # a plausible standing height, to guess a unit (ours)
UNITS_CM = {"m": 100.0, "cm": 1.0, "mm": 0.1, "in": 2.54}


def unit_guess(height: float) -> str:
    """The length unit under which ``height`` is a person's, or a sentence saying none is."""
    for unit, cm in UNITS_CM.items():
        if HUMAN_HEIGHT_CM[0] <= height * cm <= HUMAN_HEIGHT_CM[1]:
            return unit
    if not height > 0:
        return "unknown: the skeleton has no height along its up axis"
    low, high = (h / height for h in HUMAN_HEIGHT_CM)
    return (
        f"unknown: {low:.3g}-{high:.3g} cm per unit for a {HUMAN_HEIGHT_CM[0]:.0f}-"
        f"{HUMAN_HEIGHT_CM[1]:.0f} cm person"
    )


def check_roles(rig_name: str, roles: Mapping[str, str], where: str) -> dict[str, str]:
    """A rig's ``roles`` table (rig joint → role), checked against :data:`ROLES`."""
    if not isinstance(roles, Mapping) or not roles:
        raise JointMapError(
            f"{where}: rig {rig_name!r} has no roles table (rig joint: role) "
            "to match a skeleton to; pass map.retarget=<a retarget map>"
        )
    unknown = sorted({str(r) for r in roles.values()} - set(ROLES))
    if unknown:
        raise JointMapError(f"{where}: unknown roles {unknown}; known: {list(ROLES)}")
    return {str(k): str(v) for k, v in roles.items()}


def retarget_mapping(
    match: Match, skeleton: Skeleton, rig_name: str, roles: Mapping[str, str]
) -> dict:
    """The retarget map (as ``conf/retarget/*.yaml`` holds it) the match gives for a rig;
    rig joints whose role was not found are :data:`UNKNOWN` (required) or left out."""
    joints = {}
    for rig_joint, role in roles.items():
        if role in match.roles:
            joints[rig_joint] = match.roles[role]
        elif role not in OPTIONAL_ROLES:
            joints[rig_joint] = UNKNOWN
    used = set(joints.values())
    return {
        "rig": rig_name,
        "up": match.up or UNKNOWN,
        "forward": match.forward or UNKNOWN,
        "left": match.left or UNKNOWN,
        "scale": "auto",
        "preserve_lengths": True,
        "ground": "align",
        "joints": joints,
        "ignore": [n for n in skeleton.names if n not in used],
    }


def map_text(mapping: dict, header: list[str]) -> str:
    """YAML in the shipped maps' layout (joints one a line, ignore as a flow list), with
    ``header`` as comments."""
    scalars = {k: v for k, v in mapping.items() if k not in ("joints", "ignore")}
    body = [
        yaml.safe_dump(scalars, sort_keys=False, default_flow_style=False),
        yaml.safe_dump(
            {"joints": mapping["joints"]},
            sort_keys=False,
            default_flow_style=False,
            allow_unicode=True,
        ),
        yaml.safe_dump(
            {"ignore": mapping["ignore"]}, default_flow_style=None, width=92, allow_unicode=True
        ),
    ]
    return "".join(f"# {line}\n".replace("# \n", "#\n") for line in header) + "".join(body)


# --------------------------------------------------------------------------- a BVH
@dataclass(frozen=True)
class MatchedSkeleton:
    """A BVH skeleton matched for a rig: the retarget map (and its YAML text), the match,
    the frames that are not captured motion."""

    retarget: JointMap
    text: str
    match: Match
    frames: FrameCheck

    def describe(self) -> str:
        m = self.match
        return (
            f"skeleton matched ({len(m.roles)} roles, {m.by_name} confirmed by name; up "
            f"{m.up}, forward {m.forward}, left {m.left}; height {m.height:.4g} source "
            f"units, unit {unit_guess(m.height)})"
        )


def match_bvh(
    motion,
    positions: np.ndarray,
    rig_name: str,
    roles: Mapping[str, str],
    *,
    draft: str | os.PathLike,
    source: str = "",
    notes: tuple[str, ...] = (),
) -> MatchedSkeleton:
    """Match a parsed BVH (``positions``: its joints then end sites, every frame) for the
    rig whose ``roles`` table is given. Unsure: the draft map is written to ``draft`` and
    :class:`SkeletonMatchError` names the unmatched roles and the draft."""
    source = source or motion.source
    skeleton = Skeleton.from_bvh(motion)
    match = match_skeleton(skeleton)
    frames = check_frames(motion.values, positions, skeleton.names, match)
    mapping = retarget_mapping(match, skeleton, rig_name, roles)
    unmatched = [f"{j} (role {roles[j]})" for j, s in mapping["joints"].items() if s == UNKNOWN]
    header = [
        f"Retarget map for {Path(source).name} onto rig {rig_name}, matched by",
        "rigmap.map.skeleton_match: read it, edit it if need be, pass it as map.retarget=<file>.",
    ]
    header += [*_report_lines(match, frames, len(skeleton.names)), *notes]
    if unmatched or match.problems:
        header += [
            "UNSURE (fix these, then pass this file as map.retarget=):",
            *(f"- unmatched rig joint {u}" for u in unmatched),
            *(f"- {p}" for p in match.problems),
        ]
        write_text_atomic(draft, map_text(mapping, header))
        raise SkeletonMatchError(
            f"{source}: skeleton not matched to rig {rig_name!r}: "
            + "; ".join(
                [*(["unmatched " + ", ".join(unmatched)] if unmatched else []), *match.problems]
            )
            + f"; draft retarget map written to {draft}: fix it and pass map.retarget={draft}"
        )
    text = map_text(mapping, header)
    retarget = JointMap.from_mapping(mapping, source_file=f"<{Path(source).name} matched>")
    return MatchedSkeleton(retarget, text, match, frames)


def _report_lines(match: Match, frames: FrameCheck, joints: int) -> list[str]:
    return [
        f"Source: {joints} joints and end sites; {len(match.roles)} roles found by the "
        f"hierarchy, {match.by_name} of them confirmed by their names.",
        f"Axes from the rest pose: up {match.up or '?'}, forward {match.forward or '?'} "
        f"(feet to toes), left {match.left or '?'}.",
        f"Height {match.height:.4g} source units (unit {unit_guess(match.height)});",
        "scale: auto sets rig cm per source unit from the bone lengths.",
        f"Frames: {frames.describe()}.",
    ]
