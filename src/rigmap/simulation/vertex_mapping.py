"""Simulated vertices mapped onto the rig: a vertex-subset mapping, then refinement (§6.3).

The paper places "joints" at the squirrel's mesh vertices and maps the simulation's
vertices through its learned inverse. The simulator knows nothing of the rig's centre of
gravity, so the mapping is a partial-input one (:class:`rigmap.map.partial.SubsetMapping`):
its input is the world positions of a vertex subset the config names (every ``every``-th
vertex plus the three that give its frame: an ``origin`` vertex and the ``left``/``right``
pair whose axis gives the heading), fitted once on the rig's train corpus and poses by
:func:`rigmap.map.subset_model.obtain_subset_model` and cached. Each frame's guess is then
refined by damped least squares on the subset's world positions, pulled toward the guess
(:func:`rigmap.map.clip.solve_controls`, through :mod:`rigmap.refine`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rigmap.map.clip import MapSettings, solve_controls
from rigmap.map.partial import JointSubset
from rigmap.map.subset_model import SubsetModel
from rigmap.simulation.sim_file import VertexInputError


def vertex_subset(rig, spec: Mapping) -> JointSubset:
    """The subset ``spec`` names: ``name``, ``every`` (1: every vertex), ``origin``, ``left``,
    ``right`` (vertex names such as ``v0000``), in the rig's vertex order."""
    every = spec.get("every", 1)
    if not (isinstance(every, int) and not isinstance(every, bool) and every >= 1):
        raise VertexInputError(f"simulate.subset.every={every!r}: an integer >= 1")
    frame = [spec.get(key) for key in ("origin", "left", "right")]
    kept = set(rig.joint_names[::every]) | {f for f in frame if f is not None}
    joints = [name for name in rig.joint_names if name in kept]
    data = {"joints": joints, **{k: spec.get(k) for k in ("origin", "left", "right")}}
    return JointSubset.from_mapping(data, name=str(spec.get("name", f"every{every}")), rig=rig)


def check_vertices(vertices: np.ndarray, rig, source: str = "input") -> np.ndarray:
    """``(F, V, 3)`` finite world vertices of ``rig`` (one line naming the fault otherwise)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 3 or vertices.shape[1:] != (rig.n_vertices, 3) or len(vertices) == 0:
        raise VertexInputError(
            f"{source}: vertices of shape {vertices.shape}, rig {rig.name!r} needs "
            f"(frames, {rig.n_vertices}, 3)"
        )
    bad = np.argwhere(~np.isfinite(vertices).all(axis=2))
    if len(bad):
        frame, vertex = bad[0]
        raise VertexInputError(
            f"{source}: vertex {rig.joint_names[vertex]!r} is not finite at frame {frame} "
            f"({len(bad)} bad vertex positions in all)"
        )
    return vertices


@dataclass(frozen=True)
class VertexMapping:
    """The mapped controls of every frame and what they cost."""

    controls: np.ndarray  # (F, C) every control, unused ones at their defaults
    guess: np.ndarray  # (F, C) the mapping's guess before refinement
    seconds: dict[str, float]  # predict_s, refine_s (and refine_rig_evaluations)

    @property
    def seconds_per_frame(self) -> float:
        total = self.seconds.get("predict_s", 0.0) + self.seconds.get("refine_s", 0.0)
        return total / len(self.controls)


def map_vertices(
    rig, vertices: np.ndarray, model: SubsetModel, settings: MapSettings
) -> VertexMapping:
    """Controls for each frame of ``vertices`` ``(F, V, 3)`` (world cm, every vertex of the
    rig): the subset's guess, refined on the subset's world positions."""
    vertices = check_vertices(vertices, rig)
    subset = model.mapping.subset
    world = vertices[:, subset.columns(rig)]
    seconds: dict[str, float] = {}
    started = time.perf_counter()
    guess = model.mapping.predict(world)
    guess_s = time.perf_counter() - started
    used = solve_controls(
        rig, model.mapping, world, settings, model.control_std, model.hold_values, seconds
    )
    seconds["guess_only_predict_s"] = guess_s
    return VertexMapping(rig.expand_used(used), rig.expand_used(guess), seconds)


def vertex_errors(rig, controls: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Per frame, the RMS distance (cm) of the rig's mesh at ``controls`` from ``vertices``
    over every vertex."""
    mesh = np.asarray(rig.world_vertices(np.asarray(controls, dtype=np.float64)))
    return np.sqrt(((mesh - vertices) ** 2).sum(axis=2).mean(axis=1))
