"""A method of Table 1 as an object: an initial guess, then a refiner with its Jacobian source.

A method is built from its yaml (``conf/method/<name>.yaml``) from its ``_target_``:
``_target_: rigmap.evaluation.method.Method``, a ``guess`` node (the rig's retarget script, or
a regressor by name) and a ``refine`` node from ``conf/refine/*`` (no refinement, or damped
least squares, Eq. 13, with a computed or a learned Jacobian). The guess and the refiner do the
work; nothing dispatches on a method's name. The report's label is the guess's ``title`` and
the refiner's (:mod:`rigmap.catalog`); the name is its key in the config (``method.<name>``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import lru_cache
from operator import attrgetter
from typing import Any, ClassVar

import numpy as np

from rigmap.evaluation.checks import EvaluationSetupError
from rigmap.evaluation.refine_settings import RefineSettings
from rigmap.evaluation.timing import CountingRig, ScriptCountingRig

JACOBIANS = ("finite_difference", "autodiff")


# --------------------------------------------------------------------------- guesses
class Guess:
    """How a method makes its first controls from a clip's frames."""

    kind: ClassVar[str]  # what the metrics JSON calls it ("guess")
    uses_rig: ClassVar[bool]  # whether the guess itself evaluates the rig
    regressor: str | None = None  # the fitted mapping's name (its model folder), if any
    title: str  # the report's label of the method's row (a refiner adds its own)

    def __init__(self, title: str) -> None:
        if not isinstance(title, str) or not title:
            raise EvaluationSetupError(f"guess.title: expected a label, got {title!r}")
        self.title = title

    def counting_rig(self, rig: Any) -> CountingRig:
        return CountingRig(rig)

    def check(self, method: str, regressor: Any) -> None:
        """One error naming ``method`` when the fitted model it gets does not fit the guess."""

    def __call__(self, rig, model, positions, cog, rotation, features: Callable) -> np.ndarray:
        raise NotImplementedError


class ScriptGuess(Guess):
    """The rig's own retarget script (Table 1 "Script")."""

    kind = "script"
    uses_rig = True

    def __init__(self, title: str = "Script") -> None:
        super().__init__(title)

    def counting_rig(self, rig: Any) -> CountingRig:
        return ScriptCountingRig(rig)  # a script's read-backs and constraint solves count too

    def check(self, method: str, regressor: Any) -> None:
        if regressor is not None:
            raise EvaluationSetupError(f"method {method!r} takes no regressor; one was given")

    def __call__(self, rig, model, positions, cog, rotation, features: Callable) -> np.ndarray:
        from rigmap.retarget.script import script_retarget

        return script_retarget(rig, positions, cog, rotation).Y_used


class RegressorGuess(Guess):
    """A fitted inverse mapping (``regressor``: its name, e.g. gpr, nn, mean) on pose features."""

    kind = "regressor"
    uses_rig = False

    def __init__(self, regressor: str, title: str | None = None) -> None:
        if not isinstance(regressor, str) or not regressor:
            raise EvaluationSetupError(f"guess.regressor: expected a name, got {regressor!r}")
        super().__init__(regressor if title is None else title)
        self.regressor = regressor

    def check(self, method: str, regressor: Any) -> None:
        if regressor is None:
            raise EvaluationSetupError(
                f"method {method!r} needs a fitted {self.regressor} inverse mapping "
                "(regressor=...); got none"
            )

    def __call__(self, rig, model, positions, cog, rotation, features: Callable) -> np.ndarray:
        return np.asarray(model.predict(features()), dtype=np.float64)


# --------------------------------------------------------------------------- refiners
class Refiner:
    """What a method does after its guess: nothing, or damped least squares (Eq. 13)."""

    kind: ClassVar[str]  # the refine group's ``name`` (conf/refine/<kind>.yaml)
    needs_learned_jacobian: ClassVar[bool] = False
    jacobian: str | None = None  # the computed Jacobian's method, if any
    settings: RefineSettings | None = None
    title: str | None = None  # what the report adds to the guess's label (" & <title>")

    def __init__(self, name: str) -> None:
        if name != self.kind:
            raise EvaluationSetupError(
                f"refine.name: the {type(self).__name__} refines with {self.kind!r}, got {name!r}"
            )

    @classmethod
    def title_of(cls, config: Mapping[str, Any]) -> str | None:
        """The label a refine node of this class adds (for the catalogue, nothing built)."""
        return cls.title

    def check(self, method: str, rig: Any, learned_jacobian: Any) -> None:
        """One error naming ``method`` when the rig or the models cannot serve the refiner."""

    def __call__(self, rig, Y_used, positions, features, learned, train_std, settings):
        """``(refined Y_used, RefineResult)``; ``settings`` override the refiner's own."""
        return Y_used, None


class NoRefinement(Refiner):
    """The guess is the answer (Table 1 "GPR", "NN", "Script")."""

    kind = "none"

    def __init__(self, name: str = "none") -> None:
        super().__init__(name)


class DampedLeastSquares(Refiner):
    """Damped least squares from the guess, with the Jacobian its subclass supplies."""

    def __init__(self, name: str, **settings: Any) -> None:
        super().__init__(name)
        self.settings = RefineSettings.from_values(settings, self.kind)

    def source(self, rig, features: Callable, learned, settings: RefineSettings):
        raise NotImplementedError

    def __call__(self, rig, Y_used, positions, features, learned, train_std, settings):
        from rigmap.refine import damped_least_squares

        settings = settings if settings is not None else self.settings
        refined = damped_least_squares(
            rig,
            Y_used,
            positions,
            self.source(rig, features, learned, settings),
            damping=settings.damping,
            tolerance=settings.tolerance,
            max_iterations=settings.max_iterations,
            control_scale=train_std if settings.control_scale == "training_std" else None,
            keep_in_range=settings.keep_in_range,
            solver=settings.solver,
            reuse=settings.reuse(),
            threads=settings.threads,
            traced=settings.traced,
        )
        return refined.Y_used, refined


class ComputedJacobianRefinement(DampedLeastSquares):
    """The rig's own Jacobian, by finite differences or (built-in rigs) autodiff (§4.3)."""

    kind = "computed_jacobian"
    #: the report's label per Jacobian method (the paper's "Computed Jacobian"; autodiff ours)
    TITLES: ClassVar[dict[str, str]] = {
        "finite_difference": "Computed Jacobian",
        "autodiff": "Autodiff Jacobian",
    }

    def __init__(self, name: str, jacobian: str = "finite_difference", **settings: Any):
        super().__init__(name, **settings)
        if jacobian not in JACOBIANS:
            raise EvaluationSetupError(
                f"refine.jacobian: expected one of {JACOBIANS}, got {jacobian!r}"
            )
        self.jacobian = jacobian
        self.title = self.title_of({"jacobian": jacobian})

    @classmethod
    def title_of(cls, config: Mapping[str, Any]) -> str | None:
        return cls.TITLES.get(config.get("jacobian", "finite_difference"))

    def check(self, method: str, rig: Any, learned_jacobian: Any) -> None:
        if self.jacobian == "autodiff" and not getattr(rig, "differentiable", False):
            raise EvaluationSetupError(
                f"method {method!r} needs autodiff, but rig {rig.name!r} is not differentiable"
            )

    def source(self, rig, features: Callable, learned, settings: RefineSettings):
        from rigmap.refine import ComputedJacobian

        return ComputedJacobian(
            rig, self.jacobian, settings.differences, sparsity=settings.sparsity
        )


class LearnedJacobianRefinement(DampedLeastSquares):
    """The Jacobian a GPR learned (§4.4), predicted once per frame: no rig evaluation."""

    kind = "learned_jacobian"
    needs_learned_jacobian = True
    title = "Learned Jacobian"

    def check(self, method: str, rig: Any, learned_jacobian: Any) -> None:
        if learned_jacobian is None:
            raise EvaluationSetupError(
                f"method {method!r} needs a learned Jacobian (learned_jacobian=...); got none"
            )

    def source(self, rig, features: Callable, learned, settings: RefineSettings):
        from rigmap.refine import PredictedJacobian

        return PredictedJacobian(learned, features())


# --------------------------------------------------------------------------- methods
class Method:
    """One row of Table 1: a guess and a refiner, under the name its config gives it."""

    def __init__(
        self,
        name: str,
        guess: Guess,
        refine: Refiner | None = None,
        extra: bool = False,
        tune: Mapping[str, Any] | None = None,
    ) -> None:
        refine = NoRefinement() if refine is None else refine
        if not isinstance(guess, Guess):
            raise EvaluationSetupError(
                f"method {name!r}: guess must be a Guess (its _target_), got {type(guess).__name__}"
            )
        if not isinstance(refine, Refiner):
            raise EvaluationSetupError(
                f"method {name!r}: refine must be a Refiner (conf/refine/*.yaml's _target_), "
                f"got {type(refine).__name__}"
            )
        self.name, self.guess, self.refiner = str(name), guess, refine
        if not isinstance(extra, bool):
            raise EvaluationSetupError(
                f"method {name!r}: extra must be true or false, got {extra!r}"
            )
        self.extra = extra  # a row the paper does not have (the report marks it)
        # the regressor tuned on each target clip inside the clock (regression.target_tuning)
        self.tune = dict(tune) if tune is not None else None
        self.config: dict[str, Any] = {}  # the plain config node it was built from (the record)

    @property
    def title(self) -> str:
        """The report's label: the guess's, then `` & `` and the refiner's if it refines."""
        if self.refiner.title is None:
            return self.guess.title
        return f"{self.guess.title} & {self.refiner.title}"

    # the guess's and the refiner's own values, read off the method (runner, jobs, its record)
    regressor = property(attrgetter("guess.regressor"))
    refine = property(
        attrgetter("refiner.kind"),
        doc="The refinement's kind: ``none``, ``computed_jacobian`` or ``learned_jacobian``.",
    )
    jacobian = property(attrgetter("refiner.jacobian"))
    refine_settings = property(attrgetter("refiner.settings"))
    needs_learned_jacobian = property(attrgetter("refiner.needs_learned_jacobian"))

    @property
    def uses_rig_during_retarget(self) -> bool:
        """Whether the method itself evaluates the rig (and so is slow on a DCC rig)."""
        return self.guess.uses_rig or self.refine != "none"

    @property
    def refine_label(self) -> str:
        """``none``, ``learned_jacobian``, ``finite_difference`` or ``autodiff``."""
        return self.jacobian if self.jacobian is not None else self.refine

    def __repr__(self) -> str:
        return (
            f"Method({self.name!r}, guess={self.guess.kind}:{self.regressor}, "
            f"refine={self.refine_label})"
        )


def method_catalog(configs: Mapping[str, Mapping[str, Any]]) -> dict[str, Method]:
    """Every method of the ``method`` config node, by name, each built from its ``_target_``
    (:func:`rigmap.config_objects.instantiate_node`; the application layer's
    :func:`rigmap.app.evaluate.method_catalog` is this)."""
    from rigmap.config_objects import ConfigNodeError, instantiate_node

    catalog = {}
    for name, node in configs.items():
        try:
            built = instantiate_node(node, name=str(name))
        except (ConfigNodeError, EvaluationSetupError) as error:
            cause = error.__cause__ if error.__cause__ is not None else error
            where = f"method.{name} (conf/method/{name}.yaml)"
            raise EvaluationSetupError(f"{where}: {cause}") from None
        if not isinstance(built, Method):
            raise EvaluationSetupError(
                f"method.{name}: its _target_ built a {type(built).__name__}, expected a "
                "Method (rigmap.evaluation.method.Method)"
            )
        refine = {k: v for k, v in dict(node.get("refine") or {}).items() if k != "_target_"}
        built.config = {  # what an MLflow run records as the method's own settings
            "guess": built.guess.kind,
            "regressor": built.regressor,
            "refine": refine or {"name": built.refine},
            "tune": built.tune,
        }
        catalog[str(name)] = built
    return catalog


@lru_cache(maxsize=1)
def packaged_methods() -> dict[str, Method]:
    """The package's methods as its own config composes them (for callers without a config)."""
    from rigmap.catalog import packaged_conf
    from rigmap.config_objects import compose_group

    return method_catalog(compose_group(packaged_conf(), "method"))


def get_method(name: str) -> Method:
    """The package's method ``name`` (``conf/method/<name>.yaml``), or an error listing them."""
    methods = packaged_methods()
    try:
        return methods[name]
    except KeyError:
        raise EvaluationSetupError(
            f"unknown method {name!r}; available methods: {', '.join(methods)}"
        ) from None
