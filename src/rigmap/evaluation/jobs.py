"""What one evaluate stage runs: a job per method run, its fitted models and its metrics file.

The three evaluation sets of the paper: ``methods`` (Table 1 and its extra rows),
``samplers`` (Table 2: the network once per sampler) and ``kernels`` (§7.1: the GPR
once per kernel). A job names its models by :class:`rigmap.store.ModelId` and its
metrics file by :class:`rigmap.store.Layout`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from rigmap.evaluation.checks import EvaluationSetupError
from rigmap.evaluation.method import Method, packaged_methods
from rigmap.store import Layout, ModelId

EVALUATION_SETS = ("methods", "samplers", "kernels")
#: what a set is scored on: the library's (extreme) test clips, new takes of the training
#: motions (in-distribution, issue #15), or the training frames themselves (training error)
TEST_SPLITS = ("test", "heldout", "train")


@dataclass(frozen=True)
class EvaluationJob:
    """One method run of an evaluate stage: which models it reads and where its metrics go."""

    method: Method
    sampler: str  # the sampler the regressor's training data came from ("none" for gpr/script)
    kernel: str | None  # the GPR kernel (None for nn and script)
    metrics_path: Path  # <metrics>/<rig>/<set>/<stem>.json (per-frame CSV: per_frame_file)
    jacobian_kernel: str | None = None  # kernel of the GPR folder holding the learned Jacobian

    @property
    def model_id(self) -> ModelId | None:
        """The fitted mapping the guess comes from, or None for the script."""
        if self.method.regressor is None:
            return None
        return ModelId(self.method.regressor, self.sampler, self.kernel or "none")

    @property
    def jacobian_model_id(self) -> ModelId | None:
        """The GPR whose ``learned_jacobian/`` refinement reads, if it needs one."""
        if not self.method.needs_learned_jacobian:
            return None
        return ModelId("gpr", "none", self.jacobian_kernel)


def evaluation_jobs(
    set_name: str,
    rig: str,
    metrics_folder: str | Path,
    *,
    methods: Sequence[str] | None = None,
    samplers: Sequence[str] = (),
    kernels: Sequence[str] = (),
    nn_sampler: str = "pca_gaussian",
    gpr_kernel: str = "multiquadric",
    catalog: Mapping[str, Method] | None = None,
    test_split: str = "test",
    replicate: int | None = None,
) -> list[EvaluationJob]:
    """The runs of one evaluate stage; ``catalog`` holds the methods by name (``None``: the
    package's own, :func:`rigmap.evaluation.method.packaged_methods`; ``methods`` ``None``: all).

    - ``methods``: each method once; GPR methods read ``gpr-none-<gpr_kernel>``,
      network methods ``nn-<nn_sampler>-none``, learned-Jacobian refinement the
      ``learned_jacobian/`` of ``gpr-none-<gpr_kernel>``; files
      ``methods/<method>-<sampler>.json``.
    - ``samplers``: ``nn`` once per sampler; files ``samplers/nn-<sampler>.json``.
    - ``kernels``: ``gpr`` once per kernel; files ``kernels/gpr-<kernel>.json``.
    """
    if set_name not in EVALUATION_SETS:
        raise EvaluationSetupError(
            f"evaluate.set: expected one of {EVALUATION_SETS}, got {set_name!r}"
        )
    catalog = packaged_methods() if catalog is None else catalog
    methods = tuple(catalog) if methods is None else methods
    folder = set_folder(set_name, test_split)
    root = Layout(metrics=Path(metrics_folder), replicate=replicate).metrics_folder(rig, folder)
    jobs = []
    if set_name == "methods":
        for name in methods:
            method = _method(catalog, name)
            sampler = nn_sampler if method.regressor == "nn" else "none"
            kernel = gpr_kernel if method.regressor == "gpr" else None
            jacobian_kernel = gpr_kernel if method.needs_learned_jacobian else None
            path = root / f"{name}-{sampler}.json"
            jobs.append(EvaluationJob(method, sampler, kernel, path, jacobian_kernel))
    elif set_name == "samplers":
        network = _method(catalog, "nn")
        for sampler in samplers:
            jobs.append(EvaluationJob(network, sampler, None, root / f"nn-{sampler}.json"))
    else:
        gpr = _method(catalog, "gpr")
        for kernel in kernels:
            jobs.append(EvaluationJob(gpr, "none", kernel, root / f"gpr-{kernel}.json"))
    if not jobs:
        raise EvaluationSetupError(f"evaluate.set={set_name}: nothing to run (empty list)")
    stems = [job.metrics_path.name for job in jobs]
    repeated = sorted({s for s in stems if stems.count(s) > 1})
    if repeated:
        raise EvaluationSetupError(f"evaluate.set={set_name}: runs repeated: {repeated}")
    return jobs


def set_folder(set_name: str, test_split: str) -> str:
    """The metrics folder of a set scored on a split: ``methods`` on the test clips,
    ``methods_heldout`` on the held-out takes, ``methods_train`` on the training frames."""
    if test_split not in TEST_SPLITS:
        raise EvaluationSetupError(
            f"evaluate.test_split: expected one of {TEST_SPLITS}, got {test_split!r}"
        )
    return set_name if test_split == "test" else f"{set_name}_{test_split}"


def _method(catalog: Mapping[str, Method], name: str) -> Method:
    try:
        return catalog[name]
    except KeyError:
        raise EvaluationSetupError(
            f"unknown method {name!r}; available methods: {', '.join(catalog)}"
        ) from None
