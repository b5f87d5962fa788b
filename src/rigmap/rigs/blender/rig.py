"""A rig that lives in a .blend file and is evaluated by Blender worker processes.

The rig is a black box here, as in the paper (§3.2, §4.4): controls go to the
workers, deform-bone heads come back; no gradients (``differentiable=False``).
The control table is discovered by a worker once and cached next to the rig
cache, so listing or describing a rig does not start Blender the second time.

Units and axes: centimetres (Blender metres x ``length_scale`` = 100) and
radians; positions in rigmap's axes like the other built-in rigs (Y up, the
character facing +Z, +X its left), converted from Blender's Z-up world
(``up_axis="Z"`` keeps Blender's). Translation controls are in the bone's own
space, in centimetres. Rotation controls are Euler angles: control bones that
rotate by quaternion are switched to Euler (``euler_order``, default XYZ) when
the file is opened, so every rotation channel is one angle an animator keys.
Custom properties are clamped to their hard range, as Blender clamps keyframes.
``soft_ranges`` widens (or narrows) the animator's working range of chosen controls.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from fnmatch import fnmatchcase
from pathlib import Path

import numpy as np

from rigmap.rigs.base import Control, ControlTable, Pose, Rig, RigInputError, _is_torch
from rigmap.rigs.blender.cache import cache_dir, read_json, write_json_atomic
from rigmap.rigs.blender.environment import BlenderCommand, find_blender
from rigmap.rigs.blender.in_blender.protocol import PROTOCOL_VERSION
from rigmap.rigs.blender.pool import DEFAULT_CHUNK_ROWS, WorkerPool, default_worker_count
from rigmap.rigs.blender.retarget import solve_constraints

# Bumped when what a worker reports about a rig changes, so stale descriptions are ignored.
DESCRIPTION_FORMAT = 5
RIGIFY_HELPER_BONES = ["DEF-*", "MCH-*", "ORG-*", "VIS_*"]


def _patterns(selection, where: str) -> tuple[list[str], list[str]]:
    """``include``/``exclude`` glob lists from a list (include only) or a mapping."""
    if selection is None:
        return ["*"], []
    if isinstance(selection, str):
        return [selection], []
    if isinstance(selection, Mapping):
        unknown = set(selection) - {"include", "exclude"}
        if unknown:
            raise ValueError(f"{where}: unknown keys {sorted(unknown)}; expected include/exclude")
        return list(selection.get("include") or ["*"]), list(selection.get("exclude") or [])
    if isinstance(selection, Sequence):
        return list(selection), []
    raise TypeError(
        f"{where}: expected a list of patterns or {{include, exclude}}, got {selection!r}"
    )


def session_options(
    path: Path,
    *,
    where: str,
    armature: str | None,
    cog_bone: str | None,
    joints=None,
    control_bones=None,
    exclude_bones: list[str] | None = None,
    euler_order: str = "XYZ",
    length_scale: float = 100.0,
    up_axis: str = "Y",
    translate_range: float = 30.0,
    scale_range: Sequence[float] = (0.25, 3.0),
    use_scripts: bool = False,
) -> dict:
    """The worker's ``load`` options for the armature in ``path``: one spelling, and one
    set of defaults, for :class:`BlenderRig` and the .blend corpus import, which hand their
    other armature options on as ``**load`` (``where`` names the caller in errors)."""
    include, exclude = _patterns(joints, f"{where} joints")
    return {
        "path": str(path),
        "armature": armature,
        "cog_bone": cog_bone,
        "control_bones": _patterns(control_bones, f"{where} control_bones")[0],
        "exclude_bones": list(RIGIFY_HELPER_BONES if exclude_bones is None else exclude_bones),
        "joints": {"include": include, "exclude": exclude},
        "euler_order": euler_order,
        "length_scale": float(length_scale),
        "up_axis": str(up_axis),
        "translate_range": float(translate_range),
        "scale_range": [float(s) for s in scale_range],
        "use_scripts": bool(use_scripts),
    }


def select_names(names: list[str], selection, where: str) -> list[bool]:
    """Which ``names`` the glob selection picks; an include pattern that picks none is an error."""
    include, exclude = _patterns(selection, where)
    dead = [p for p in include if not any(fnmatchcase(n, p) for n in names)]
    if dead:
        raise ValueError(f"{where}: patterns {dead} match no name (names look like {names[:6]})")
    return [
        any(fnmatchcase(n, p) for p in include) and not any(fnmatchcase(n, p) for p in exclude)
        for n in names
    ]


def soft_range_overrides(
    names: list[str], defaults: list[float], ranges: Mapping | None, where: str
) -> dict[int, tuple[float, float]]:
    """Control index -> ``(lower, upper)`` from ``{glob pattern: [lower, upper]}``.

    The backend's ranges (translations ``translate_range`` around rest, rotations ±π)
    fit a hand or a foot; a character that walks across the room or sits down needs
    wider ones on its root and body. Later patterns win over earlier ones.
    """
    chosen: dict[int, tuple[float, float]] = {}
    for pattern, bounds in (ranges or {}).items():
        try:
            lower, upper = (float(b) for b in bounds)
        except (TypeError, ValueError):
            raise ValueError(
                f"{where}: {pattern!r} needs [lower, upper] numbers, got {bounds!r}"
            ) from None
        if not (np.isfinite(lower) and np.isfinite(upper) and lower < upper):
            raise ValueError(f"{where}: {pattern!r} needs finite lower < upper, got {bounds!r}")
        hits = [i for i, n in enumerate(names) if fnmatchcase(n, str(pattern))]
        if not hits:
            raise ValueError(
                f"{where}: pattern {pattern!r} matches no control (names look like {names[:6]})"
            )
        for i in hits:
            if not lower <= defaults[i] <= upper:
                raise ValueError(
                    f"{where}: {pattern!r} range [{lower:g}, {upper:g}] leaves out the default "
                    f"{defaults[i]:g} of control {names[i]!r}"
                )
            chosen[i] = (lower, upper)
    return chosen


def _control_table(controls: list[dict], used, soft_ranges, name: str) -> ControlTable:
    """The controls Blender described, with the config's used flags and soft ranges."""
    names = [c["name"] for c in controls]
    used_flags = select_names(names, used, f"rig {name!r} used")
    ranges = soft_range_overrides(
        names, [c["default"] for c in controls], soft_ranges, f"rig {name!r} soft_ranges"
    )
    return ControlTable(
        [
            Control(
                c["name"],
                c["kind"],
                c["default"],
                *ranges.get(i, (c["lower"], c["upper"])),
                flag,
                c["group"],
            )
            for i, (c, flag) in enumerate(zip(controls, used_flags, strict=True))
        ]
    )


EXECUTORS = ("local", "ray")


def executor_options(executor, name: str) -> dict:
    """``{"kind": "local"|"ray", ...}`` from ``None``, a kind, or a mapping (``conf/executor``).

    ``ray`` keys: ``address`` (null: ``RAY_ADDRESS`` or a new local head; ``auto``; host:port)
    and ``actors`` (null: the rig's ``workers``, else one per core).
    """
    if executor is None:
        return {"kind": "local"}
    options = {"kind": executor} if isinstance(executor, str) else dict(executor)
    kind = options.get("kind")
    if kind not in EXECUTORS:
        raise RigInputError(
            f"rig {name!r}: executor kind must be one of {list(EXECUTORS)}, got {kind!r}"
        )
    known = {"kind"} | ({"address", "actors"} if kind == "ray" else set())
    unknown = set(options) - known
    if unknown:
        raise RigInputError(
            f"rig {name!r}: executor {kind!r} takes {sorted(known)}, not {sorted(unknown)}"
        )
    actors = options.get("actors")
    if actors is not None and (
        isinstance(actors, bool) or not isinstance(actors, int) or actors < 1
    ):
        raise RigInputError(f"rig {name!r}: executor actors must be >= 1, got {actors!r}")
    return options


class BlenderRig(Rig):
    """An armature in a .blend file, evaluated out of process by a :class:`WorkerPool`.
    ``load``: the armature options of :func:`session_options` (``joints``, ``euler_order``…),
    whose defaults are kept there, shared with the .blend corpus import."""

    differentiable = False
    computes_in_float32 = True  # Blender's bone matrices and properties are float32
    length_unit = "cm"

    def __init__(
        self,
        name: str,
        path: str | Path,
        *,
        armature: str = "rig",
        cog_bone: str = "torso",
        used=None,
        soft_ranges: Mapping[str, Sequence[float]] | None = None,
        prune: bool = True,
        workers: int | None = None,
        timeout: float = 120.0,
        chunk_rows: int = DEFAULT_CHUNK_ROWS,
        pin_cpus: bool | str = "auto",
        blender: str | None = None,
        retarget: list[dict] | None = None,
        executor: str | Mapping | None = None,
        description: str = "",
        **load,
    ):
        path = Path(path).expanduser().resolve()
        if not path.is_file():
            raise FileNotFoundError(f"rig {name!r}: blend file {path} does not exist")
        if workers is not None and (
            isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
        ):
            raise RigInputError(
                f"rig {name!r}: workers must be a whole number >= 1 (or null: one per core), "
                f"got {workers!r}"
            )
        options = session_options(
            path, where=f"rig {name!r}", armature=armature, cog_bone=cog_bone, **load
        )
        self.name = name
        self.path = path
        self.description = description or f"{armature!r} in {path.name}, evaluated by Blender"
        self.session_options = {**options, "prune": bool(prune)}
        self.command: BlenderCommand = find_blender(blender)
        self.workers = workers
        self.timeout = float(timeout)
        self.chunk_rows = int(chunk_rows)
        self.pin_cpus = pin_cpus
        self.retarget_mapping = list(retarget or [])
        self.executor = executor_options(executor, name)
        self._pool: WorkerPool | None = None

        try:  # a rig that fails to build leaves no worker behind
            info = self._describe()
            self.controls = _control_table(info["controls"], used, soft_ranges, name)
        except BaseException:
            self.close()
            raise
        controls = info["controls"]
        self.channels = controls  # per control: bone, attribute/axis or property (for export)
        self.joint_names = list(info["joint_names"])
        self.parents = np.asarray(info["parents"], dtype=np.int64)
        self.stats = dict(info["stats"])
        self.blender_version = info["blender_version"]

    # --- workers --------------------------------------------------------------
    def _argv(self, slot: int) -> list[str]:
        return self.command.argv(*(["--pin-cpu", str(slot)] if self._pinned() else []))

    def _pinned(self) -> bool:
        """Give each worker a core of its own when there are as many workers as cores.

        Blender then runs its depsgraph on one thread per worker instead of every
        worker's threads fighting over all cores ("auto"); fewer workers than
        cores keep Blender's own threading.
        """
        if self.pin_cpus == "auto":
            return (self.workers or default_worker_count()) >= default_worker_count()
        return bool(self.pin_cpus)

    @property
    def pool(self) -> WorkerPool:
        """The rig's workers, started on first use."""
        if self._pool is None:
            if self.executor["kind"] == "ray":
                self._pool = self.make_ray_pool()
            else:
                self._pool = self.make_pool(self.session_options, workers=self.workers)
        return self._pool

    def use_executor(self, executor) -> None:
        """Evaluate on ``executor`` from now on (``conf/executor``); running workers are stopped."""
        options = executor_options(executor, self.name)
        if options != self.executor:
            self.close()
            self.executor = options

    def make_ray_pool(self):
        """The rig's evaluation workers as Ray actors, each holding the loaded .blend."""
        from rigmap.rigs.blender.ray_pool import RayWorkerPool

        return RayWorkerPool(
            self._argv,
            setup=[("load", {"options": self.session_options})],
            actors=int(self.executor.get("actors") or self.workers or default_worker_count()),
            address=self.executor.get("address"),
            timeout=self.timeout,
            log_dir=cache_dir() / "logs",
        )

    def make_pool(self, session_options: dict, *, workers: int | None) -> WorkerPool:
        return WorkerPool(
            self._argv,
            setup=[("load", {"options": session_options})],
            workers=workers,
            timeout=self.timeout,
            log_dir=cache_dir() / "logs",
        )

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    # --- description ----------------------------------------------------------
    def _description_path(self) -> Path:
        stat = self.path.stat()
        key = json.dumps(
            [
                self.session_options,
                stat.st_size,
                stat.st_mtime_ns,
                self.command.cache_tag,
                PROTOCOL_VERSION,
                DESCRIPTION_FORMAT,
            ],
            sort_keys=True,
        )
        digest = hashlib.sha256(key.encode()).hexdigest()[:24]
        return cache_dir() / "describe" / f"{self.path.stem}-{digest}.json"

    def _describe(self) -> dict:
        cached_path = self._description_path()
        cached = read_json(cached_path)
        if cached is not None:
            return cached
        self.pool.start()
        info = self.pool.setup_replies[0]["description"]
        write_json_atomic(cached_path, info)
        return info

    def describe(self) -> dict:
        """Counts a person reads: controls by kind and group, joints, bones, Blender."""
        return {
            "name": self.name,
            "backend": "blender",
            "blend_file": str(self.path),
            "armature": self.session_options["armature"],
            "blender_version": self.blender_version,
            "length_unit": self.length_unit,
            "rotation_unit": "rad (Euler " + self.session_options["euler_order"] + ")",
            "controls": self.controls.summary(),
            "joints": self.n_joints,
            "bones": self.stats,
        }

    # --- the script baseline ---------------------------------------------------
    def constraint_retarget(self, positions, cog=None, cog_rotation=None, *, mapping=None):
        """Full control vectors ``(N, C)`` from the constraint-based retarget (one solve a frame).

        See :func:`rigmap.rigs.blender.retarget.solve_constraints`; the mapping
        defaults to the rig's ``retarget`` list.
        """
        return solve_constraints(self, positions, cog, cog_rotation, mapping=mapping)

    # --- evaluation -----------------------------------------------------------
    def _pose(self, Y) -> Pose:
        torch_like = Y if _is_torch(Y) else None
        if torch_like is not None:
            Y = Y.detach().cpu().numpy()
        pose = self._run(Y, None)
        if torch_like is not None:
            import torch

            return Pose(*(torch.as_tensor(p, dtype=torch_like.dtype) for p in pose))
        return Pose(*(p.astype(Y.dtype, copy=False) for p in pose))

    def evaluate_with_progress(self, Y, on_chunk_done) -> Pose:
        """Like :meth:`pose`, calling ``on_chunk_done(rows)`` as chunks finish (progress bars)."""
        Y, squeeze = self._check_controls(Y)
        if _is_torch(Y):
            Y = Y.detach().cpu().numpy()
        pose = self._run(Y, on_chunk_done)
        return Pose(*(p[0] for p in pose)) if squeeze else pose

    def _run(self, Y: np.ndarray, on_chunk_done) -> Pose:
        out = self.pool.map_rows(
            "evaluate",
            {"controls": np.asarray(Y, dtype=np.float64)},
            chunk_rows=self.chunk_rows,
            on_chunk_done=on_chunk_done,
        )
        return Pose(out["positions"], out["cog"], out["cog_rotation"])
