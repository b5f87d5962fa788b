"""The damped-least-squares settings a refining method runs with (``conf/refine/*.yaml``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from rigmap.evaluation.checks import EvaluationSetupError

CONTROL_SCALES = ("training_std", "none")  # the metric refinement damps its steps in


@dataclass(frozen=True)
class RefineSettings:
    """Damped least squares settings: λ, tolerance (cm²), iteration cap, step metric, ranges.

    ``control_scale`` ``"training_std"`` damps the step in training standard
    deviations of the controls (λ in cm per std), ``"none"`` in each control's
    own unit (λ in cm per unit, the literal Eq. 13); ``keep_in_range`` keeps
    refined controls inside their soft ranges (see rigmap.refine, issue #7).
    ``solver`` (block_cholesky | cholesky | svd), ``differences`` (central | forward),
    ``share_every`` and ``jacobian_update`` choose how the step is solved and how a
    computed Jacobian is reused (``rigmap.refine.jacobian_reuse``, issue #16);
    ``sparsity`` (dense | coloured) whether it differences structurally
    independent controls together (``rigmap.refine.sparsity``); ``threads`` the
    torch threads refinement runs on (``None``: torch's own setting); ``traced``
    whether a built-in rig is evaluated by its TorchScript traces (issue #16; true in
    ``conf/refine`` since session 28, while these fields keep the original refinement's
    values, as the solver's and the differences' do).
    """

    damping: float | str = "auto"
    tolerance: float = 1e-4
    max_iterations: int = 10
    control_scale: str = "training_std"
    keep_in_range: bool = True
    solver: str = "cholesky"
    differences: str = "central"
    share_every: int = 1
    jacobian_update: str = "recompute"
    sparsity: str = "dense"
    threads: int | None = 1
    traced: bool = False

    def __post_init__(self) -> None:
        number = isinstance(self.damping, int | float) and np.isfinite(self.damping)
        if self.damping != "auto" and not (number and self.damping >= 0):
            raise EvaluationSetupError(
                f"refine.damping: expected a number >= 0 (cm) or 'auto', got {self.damping!r}"
            )
        if not (isinstance(self.tolerance, int | float) and self.tolerance >= 0):
            raise EvaluationSetupError(
                f"refine.tolerance: expected a number >= 0 (cm²), got {self.tolerance!r}"
            )
        if int(self.max_iterations) != self.max_iterations or self.max_iterations < 0:
            raise EvaluationSetupError(
                f"refine.max_iterations: expected an integer >= 0, got {self.max_iterations!r}"
            )
        for flag in ("keep_in_range", "traced"):
            if not isinstance(getattr(self, flag), bool):
                raise EvaluationSetupError(
                    f"refine.{flag}: expected true or false, got {getattr(self, flag)!r}"
                )
        if self.threads is not None and not (isinstance(self.threads, int) and self.threads >= 1):
            raise EvaluationSetupError(
                f"refine.threads: expected an integer >= 1 or null, got {self.threads!r}"
            )
        if not (isinstance(self.share_every, int) and self.share_every >= 1):
            raise EvaluationSetupError(
                f"refine.share_every: expected an integer >= 1, got {self.share_every!r}"
            )
        self._check_choices()

    def _check_choices(self) -> None:
        """Each named option is one of its choices (``refine.<name>: expected one of …``)."""
        from rigmap.refine import DIFFERENCES, SOLVERS, SPARSITIES
        from rigmap.refine.jacobian_reuse import UPDATES

        choices = {
            "control_scale": CONTROL_SCALES,
            "solver": SOLVERS,
            "differences": DIFFERENCES,
            "jacobian_update": UPDATES,
            "sparsity": SPARSITIES,
        }
        for name, allowed in choices.items():
            value = getattr(self, name)
            if value not in allowed:
                raise EvaluationSetupError(
                    f"refine.{name}: expected one of {allowed}, got {value!r}"
                )

    def reuse(self):
        """The computed Jacobian's reuse policy (``rigmap.refine.JacobianReuse``)."""
        from rigmap.refine import JacobianReuse

        return JacobianReuse(share_every=self.share_every, update=self.jacobian_update)

    @classmethod
    def from_values(cls, config: Mapping[str, Any], where: str) -> RefineSettings:
        """From a refine group's settings (``name`` and ``jacobian`` are the refiner's)."""
        config = dict(config)
        missing = [k for k in ("damping", "tolerance", "max_iterations") if k not in config]
        if missing:
            raise EvaluationSetupError(f"refine config {where!r} lacks {missing}")
        damping = config["damping"]
        return cls(
            damping=damping if damping == "auto" else float(damping),
            tolerance=float(config["tolerance"]),
            max_iterations=int(config["max_iterations"]),
            control_scale=str(config.get("control_scale", cls.control_scale)),
            keep_in_range=config.get("keep_in_range", cls.keep_in_range),
            solver=str(config.get("solver", cls.solver)),
            differences=str(config.get("differences", cls.differences)),
            share_every=config.get("share_every", cls.share_every),
            jacobian_update=str(config.get("jacobian_update", cls.jacobian_update)),
            sparsity=str(config.get("sparsity", cls.sparsity)),
            threads=config.get("threads", cls.threads),
            traced=config.get("traced", cls.traced),
        )

    @classmethod
    def from_config(cls, config: Mapping[str, Any], method: Any) -> RefineSettings:
        """From a ``refine`` config group (conf/refine/*.yaml) composed for ``method``.

        The group must be the method's refinement (and, for a computed Jacobian,
        name the same Jacobian), so a config never silently runs another method.
        """
        config = dict(config)
        if config.get("name") != method.refine:
            raise EvaluationSetupError(
                f"method {method.name!r} refines with {method.refine!r}, but the refine config "
                f"is {config.get('name')!r}"
            )
        if method.refine == "computed_jacobian" and config.get("jacobian") != method.jacobian:
            raise EvaluationSetupError(
                f"method {method.name!r} uses the {method.jacobian} Jacobian, but refine.jacobian "
                f"is {config.get('jacobian')!r}"
            )
        return cls.from_values(config, method.refine)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)
