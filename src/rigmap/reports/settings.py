"""Which rows the report expects: rigs, methods, samplers, kernels, and what a rig leaves out.

Every expected metrics file must exist — a missing row is an error, not a gap —
so the report states up front what the experiment evaluated. Rows an
experiment does not run (the Script baseline exists only for rigs with a
retarget script; autodiff only for differentiable rigs) are listed in
``excluded_methods`` and left out on purpose. The Blender wolf's quick budget
runs Table 1 and Table 3 only: it is not among the ``sampler_rigs`` (Table 2
and the kernel table). So do a user's own files (``blend_file_rigs``, named
``blend_file:<stem>``): their rows join Table 1 and Table 3 under the file's name.
The face and the squirrel join Table 1 by the mesh family (``pipeline.mesh_table1_rigs``,
issue #42), without the Script row and the joint-space rows.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from rigmap.catalog import Catalogue, default_catalogue
from rigmap.reports.catalog import RIGS

#: methods whose network trains through the rig: built-in rigs only (left out of Blender rigs')
JOINT_SPACE_METHODS: tuple[str, ...] = (
    "nn_joint_space",
    "nn_joint_space_computed_jacobian",
    "nn_joint_space_tuned",
)
#: the evaluate stages run the script baseline only where one exists (quadruped, biped, and
#: the Blender rigs' constraint retarget), autodiff only on differentiable rigs, and the
#: joint-space network only where its fit runs (the mesh rigs' Table 1 is a small family:
#: their rig configs' ``_overrides_`` name its methods)
DEFAULT_EXCLUDED_METHODS: dict[str, tuple[str, ...]] = {
    "face": ("script", *JOINT_SPACE_METHODS),
    "squirrel": ("script", *JOINT_SPACE_METHODS),
    "rigify_wolf": ("nn_autodiff_jacobian", *JOINT_SPACE_METHODS),
}
#: a user's .blend (rig=blend_file) has no retarget script, no autodiff, no joint-space network
BLEND_FILE_EXCLUDED_METHODS: tuple[str, ...] = (
    "script",
    "nn_autodiff_jacobian",
    *JOINT_SPACE_METHODS,
)
#: rigs whose pipeline compares methods only (Table 1) — no sampler or kernel sweeps
METHODS_ONLY_RIGS: tuple[str, ...] = ("rigify_wolf",)


@dataclass(frozen=True)
class ReportSettings:
    """The rows of every table.

    ``rigs`` appear in Table 3; ``sampler_rigs`` (a subset; ``None``: every rig but
    ``METHODS_ONLY_RIGS``) in Table 2 and the kernel table; ``method_rigs`` (a subset)
    in Table 1 — the evaluate stage compares the methods on the quadruped and the
    biped, like the paper, evaluate_mesh on the face and the squirrel, and evaluate_blender
    on Rigify's wolf (a Blender rig). ``nn_sampler`` is the
    sampler whose network the Table 1 rows ``nn*`` use (their files are
    ``methods/<method>-<nn_sampler>.json``; GPR and Script rows use ``none``).
    ``clips`` restricts the expected test clips (``None``: every clip of the rig's
    test corpus). ``blend_file_rigs`` (``blend_file:<stem>``, the report stage takes them
    from ``pipeline.blender_rigs``) are users' own files: added to ``rigs`` and
    ``method_rigs``, with ``BLEND_FILE_EXCLUDED_METHODS`` left out. ``catalogue`` labels
    the rows; a method, sampler or kernel it does not know is labelled by its own name.
    """

    rigs: tuple[str, ...] = tuple(r.key for r in RIGS)
    method_rigs: tuple[str, ...] = ("quadruped", "biped", "face", "squirrel", "rigify_wolf")
    sampler_rigs: tuple[str, ...] | None = None
    methods: tuple[str, ...] | None = None  # None: the catalogue's (the evaluate lists)
    samplers: tuple[str, ...] | None = None
    kernels: tuple[str, ...] | None = None
    nn_sampler: str = "pca_gaussian"
    excluded_methods: Mapping[str, tuple[str, ...]] = field(
        default_factory=lambda: dict(DEFAULT_EXCLUDED_METHODS)
    )
    clips: tuple[str, ...] | None = None
    blend_file_rigs: tuple[str, ...] = ()
    #: the labels of the rows (rigmap.catalog); a name it does not know prints as itself
    catalogue: Catalogue = field(default_factory=default_catalogue)

    def __post_init__(self) -> None:
        own = tuple(str(r) for r in self.blend_file_rigs)
        bad = [r for r in own if not r.startswith("blend_file:")]
        if bad:
            raise ValueError(
                f"report settings: blend_file_rigs {bad} must be named "
                "blend_file:<file stem> (the rig=blend_file name)"
            )
        object.__setattr__(self, "blend_file_rigs", own)
        extra = [r for r in own if r not in self.rigs]
        object.__setattr__(self, "rigs", (*self.rigs, *extra))
        methods = tuple(self.method_rigs)
        object.__setattr__(self, "method_rigs", (*methods, *[r for r in own if r not in methods]))
        excluded = dict(self.excluded_methods)
        for rig in own:
            excluded.setdefault(rig, BLEND_FILE_EXCLUDED_METHODS)
        object.__setattr__(self, "excluded_methods", excluded)
        if not isinstance(self.catalogue, Catalogue):
            raise ValueError(
                f"report settings: catalogue must be a rigmap.catalog.Catalogue, got "
                f"{type(self.catalogue).__name__}"
            )
        for name, kind in (("methods", "method"), ("samplers", "sampler"), ("kernels", "kernel")):
            if getattr(self, name) is None:  # read here, not at import (it imports the classes)
                object.__setattr__(self, name, self.catalogue.keys(kind))
        for name in ("rigs", "methods", "samplers", "kernels"):
            values = tuple(str(v) for v in getattr(self, name))
            if not values:
                raise ValueError(f"report settings: {name} is empty; expected at least one")
            repeated = sorted({v for v in values if values.count(v) > 1})
            if repeated:
                raise ValueError(f"report settings: {name} repeats {repeated}")
            object.__setattr__(self, name, values)
        self._set_rig_subset("method_rigs", self.method_rigs)
        if self.sampler_rigs is None:
            self._set_rig_subset(
                "sampler_rigs", [r for r in self.rigs if r not in METHODS_ONLY_RIGS]
            )
        else:
            self._set_rig_subset("sampler_rigs", self.sampler_rigs)
        excluded = {
            str(rig): tuple(str(m) for m in ms) for rig, ms in self.excluded_methods.items()
        }
        object.__setattr__(self, "excluded_methods", excluded)
        if self.clips is not None:
            object.__setattr__(self, "clips", tuple(str(c) for c in self.clips))

    def _set_rig_subset(self, name: str, rigs) -> None:
        """Store ``rigs`` as the tuple ``name``; each must be one of ``self.rigs``."""
        subset = tuple(str(r) for r in rigs)
        outside = [r for r in subset if r not in self.rigs]
        if outside:
            raise ValueError(
                f"report settings: {name} {outside} are not among rigs {list(self.rigs)}"
            )
        object.__setattr__(self, name, subset)

    def methods_for(self, rig: str) -> tuple[str, ...]:
        """The Table 1 methods the experiment evaluated on ``rig`` (none off ``method_rigs``)."""
        if rig not in self.method_rigs:
            return ()
        left_out = set(self.excluded_methods.get(rig, ()))
        return tuple(m for m in self.methods if m not in left_out)

    def method_sampler(self, method: str) -> str:
        """The sampler in a method's file name: the network's for a method whose guess is the
        ``nn`` regressor (as the evaluate stage names its files), else ``none``."""
        return self.nn_sampler if self.catalogue.method(method).regressor == "nn" else "none"

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any] | None) -> ReportSettings:
        """Settings from a config mapping (unknown keys are an error naming them)."""
        values = dict(values or {})
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"report settings: unknown keys {unknown}; expected {sorted(known)}")
        for name in (
            "rigs",
            "method_rigs",
            "sampler_rigs",
            "methods",
            "samplers",
            "kernels",
            "clips",
            "blend_file_rigs",
        ):
            if values.get(name) is not None:
                values[name] = _as_tuple(values[name], name)
        return cls(**values)


def _as_tuple(value: Any, name: str) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise ValueError(f"report settings: {name} must be a list, got {value!r}")
    return tuple(str(v) for v in value)
