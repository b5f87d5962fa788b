"""A method built from its config group ``conf/method/<name>.yaml`` (by the application layer's
``hydra.utils.instantiate``, :func:`rigmap.app.evaluate.method_catalog`).

Each yaml names the method's initial guess (``script`` or ``regressor`` with the
regressor's name) and pulls its refinement from ``conf/refine/*`` through its
defaults list, so the damped-least-squares settings a method runs with are the ones
its config shows (``method.<name>.refine.damping=0.3`` overrides one). The method's
name is its key in the config (``method.<name>``), passed in as ``name``, so no yaml
restates it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from rigmap.evaluation.methods import EvaluationSetupError, Method, RefineSettings


@dataclass(frozen=True)
class ConfiguredMethod:
    """A Table 1 row with the refinement settings its config gives, and that config."""

    method: Method
    refine: RefineSettings | None  # None exactly when the method does not refine
    config: dict[str, Any] = field(default_factory=dict, compare=False)  # plain, for the record
    tune: dict[str, Any] | None = None  # tuning on the target clip (regression.target_tuning)

    @property
    def name(self) -> str:
        return self.method.name


def configured_method(
    name: str,
    guess: str,
    regressor: str | None = None,
    refine: Mapping[str, Any] | None = None,
    tune: Mapping[str, Any] | None = None,
) -> ConfiguredMethod:
    """The method ``name`` from its config node: guess, regressor, and its ``refine`` group.

    ``refine`` is a composed ``conf/refine/*.yaml`` (``name`` none, computed_jacobian
    with its ``jacobian``, or learned_jacobian, plus the solver settings). ``tune``: the
    :class:`~rigmap.regression.target_tuning.TuningSettings` of a joint-space network
    tuned on each clip before it predicts it (``None``: no tuning).
    """
    refine = dict(refine or {"name": "none"})
    kind = refine.get("name")
    if kind is None:
        raise EvaluationSetupError(
            f"method {name!r}: its refine config has no name (expected one of conf/refine/*)"
        )
    jacobian = refine.get("jacobian") if kind == "computed_jacobian" else None
    method = Method(str(name), str(guess), regressor, str(kind), jacobian)
    settings = None if method.refine == "none" else RefineSettings.from_config(refine, method)
    config = {"guess": guess, "regressor": regressor, "refine": refine, "tune": tune}
    return ConfiguredMethod(method, settings, config, dict(tune) if tune is not None else None)
