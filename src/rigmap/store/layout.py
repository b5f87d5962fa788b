"""Every path of an experiment, in one place, and the name of a fitted mapping.

Stages, the CLI and the report ask a :class:`Layout` for paths instead of joining
strings, so a folder moves in one edit (issue #35: nothing else joins a project folder's
name or walks up from ``__file__``; ``tests/test_layout_paths.py`` checks both). The four
roots come from the ``paths`` config (``data``, ``models``, ``metrics``, ``reports``),
relative to the working directory. Besides them it names the checkout's files
(:meth:`Layout.project_conf`, :meth:`Layout.tracking_store`), the package's own config
(:func:`packaged_conf`, the one place that looks beside the package), a user's own runs
(``outputs/``) and the Blender cache.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

SPLITS = ("train", "test")  # what the animate and pose stages write
#: new takes of the training motions (other seeds): the in-distribution test set (issue #15)
HELDOUT = "heldout"
_NAME = re.compile(r"^[a-z0-9_]+$")
#: the four roots of the ``paths`` config, in this order
ROOTS = ("data", "models", "metrics", "reports")
CONF = "conf"  # the Hydra config folder: the checkout's, and the copy inside the package
CONFIG_NAME = "config"  # the Hydra primary config in it, ``conf/config.yaml``
#: where a user's own runs write by default (``/outputs/`` is git-ignored; ours)
USER_OUTPUTS = Path("outputs")
EDITS = "edits"  # the edit-propagation folder under data/, models/ and metrics/ of a subject
LATENT = "latent"  # the latent-synthesis folder under data/, models/ and metrics/ of a rig
MAP_PREFIX = "map-"  # a map subset's model folder: models/<rig>/map-<subset>
#: the regressors a replicate training seed re-fits (Table 1's trained networks, issue #36);
#: every other model of a replicate evaluation is seed 0's own
REPLICATED_REGRESSORS = ("nn", "nn_joint_space")
#: replicate networks: models/seeds/<k>/<rig>/<model id> (beside, not in, models/<rig>)
SEEDS = "seeds"
MAP = "map"  # the map_mocap stage's folder under data/<rig> and metrics/<rig>
MAP_SUITE = "map_suite"  # the map_suite stage's, likewise (and its page under reports/)
MAP_PARTIAL = "map_partial"  # the map_partial stage's metrics set
#: per-frame errors of the evaluation sets: ``metrics/<rig>/per_frame/<set>/``, apart from the
#: set's JSON so that DVC reads the set's folder as metrics and this one as plots
PER_FRAME = "per_frame"
MAP_STAGE_MODEL = "model"  # a map stage's own map model, inside its output (refitted each run)
#: the check_params stage's output, which every stage reads (``data/params_checked.txt``)
PARAMS_STAMP = "params_checked.txt"
TRACKING_STORE = "mlruns.db"  # the project's own MLflow store, at the checkout's root
CACHE_ENV_VAR = "RIGMAP_CACHE"  # where generated rigs are cached (default ~/.cache/rigmap)


def packaged_conf() -> Path:
    """The Hydra config shipped inside the package, ``rigmap/conf``: a symlink to the
    checkout's ``conf/`` in a source tree, copied files in a wheel (pyproject's
    package-data). The one lookup beside the package; nothing climbs to a checkout."""
    return Path(__file__).resolve().parents[1] / CONF


def source_checkout() -> Path | None:
    """The checkout rigmap runs from when installed editable (its ``rigmap/conf`` symlink
    leads there), else None (a wheel): where the project's own store and Blender live."""
    root = packaged_conf().resolve().parent
    try:
        is_ours = 'name = "rigmap"' in (root / "pyproject.toml").read_text(encoding="utf-8")
    except OSError:
        return None
    return root if is_ours else None


def find_project_root(start: str | os.PathLike | None = None) -> Path | None:
    """The nearest folder at or above ``start`` (default: cwd) holding ``dvc.yaml`` and
    ``conf/config.yaml``, the checkout the pipeline and its tracking store live in; None if
    there is none (each caller says what that means for it)."""
    start = (Path.cwd() if start is None else Path(start)).resolve()
    for folder in (start, *start.parents):
        conf = Layout.project_conf(folder) / f"{CONFIG_NAME}.yaml"
        if (folder / "dvc.yaml").is_file() and conf.is_file():
            return folder
    return None


@dataclass(frozen=True)
class ModelId:
    """A fitted mapping's identity: regressor, sampler of its extra samples, kernel.

    Its folder name is ``<regressor>-<sampler>-<kernel>`` (kernel ``none`` for models
    without one), e.g. ``gpr-none-multiquadric`` or ``nn-pca_gaussian-none``.
    """

    regressor: str
    sampler: str = "none"
    kernel: str = "none"

    def __post_init__(self) -> None:
        for field in ("regressor", "sampler", "kernel"):
            value = getattr(self, field)
            if not isinstance(value, str) or not _NAME.match(value):
                raise ValueError(
                    f"model id {field} {value!r} must be lower-case letters, digits and "
                    "underscores (it becomes part of a folder name)"
                )

    @property
    def folder_name(self) -> str:
        return f"{self.regressor}-{self.sampler}-{self.kernel}"

    @classmethod
    def parse(cls, folder_name: str) -> ModelId:
        """The id a folder name stands for; ``ValueError`` names a malformed one."""
        parts = str(folder_name).split("-")
        if len(parts) != 3:
            raise ValueError(
                f"model folder name {folder_name!r} is not <regressor>-<sampler>-<kernel>"
            )
        return cls(*parts)

    def __str__(self) -> str:
        return self.folder_name


@dataclass(frozen=True)
class Layout:
    """The experiment's folders: ``data/<rig>/…``, ``models/<rig>/…``, ``metrics/<rig>/…``."""

    ROOTS = ROOTS

    data: Path = Path("data")
    models: Path = Path("models")
    metrics: Path = Path("metrics")
    reports: Path = Path("reports")
    #: a replicate training seed (issue #36): its networks' models and its ``methods``
    #: metrics get folders of their own; None is the committed run (seed 0)
    replicate: int | None = None

    def __post_init__(self) -> None:
        for field in ROOTS:
            object.__setattr__(self, field, Path(getattr(self, field)))
        check_replicate(self.replicate)

    @classmethod
    def from_paths(cls, paths: Mapping | None, replicate: int | None = None) -> Layout:
        """From a ``paths`` config mapping (missing keys keep their defaults) and the
        ``replicate`` option."""
        paths = dict(paths or {})
        unknown = sorted(set(paths) - set(ROOTS))
        if unknown:
            raise ValueError(f"paths config has unknown keys {unknown}")
        roots = {k: Path(os.fspath(v)) for k, v in paths.items() if v is not None}
        return cls(**roots, replicate=replicate)

    @classmethod
    def of_project(cls, project: str | os.PathLike) -> Layout:
        """The default roots inside the checkout ``project`` (``<project>/data`` …)."""
        return cls(**{root: Path(project) / root for root in ROOTS})

    # --- the checkout and the package --------------------------------------------------
    @staticmethod
    def project_conf(project: str | os.PathLike) -> Path:
        """The checkout's Hydra config: ``<project>/conf``."""
        return Path(project) / CONF

    @staticmethod
    def tracking_store(project: str | os.PathLike) -> Path:
        """The project's own MLflow SQLite store: ``<project>/mlruns.db``."""
        return Path(project) / TRACKING_STORE

    @staticmethod
    def latent_scripts() -> Path:
        """The shipped synthesis scripts: ``rigmap/conf/latent/scripts/``."""
        return packaged_conf() / LATENT / "scripts"

    @staticmethod
    def blender_cache() -> Path:
        """Generated rigs and rig descriptions: ``$RIGMAP_CACHE/blender``, by default
        ``~/.cache/rigmap/blender`` (outside the project: shared by every checkout)."""
        root = os.environ.get(CACHE_ENV_VAR)
        base = Path(root).expanduser() if root else Path.home() / ".cache" / "rigmap"
        return base / "blender"

    # --- data/<rig>/ -------------------------------------------------------------------
    def rig_data(self, rig: str) -> Path:
        return self.data / rig

    def corpus(self, rig: str, split: str) -> Path:
        """The animator clips of one split: ``data/<rig>/corpus/<split>.parquet``
        (the held-out takes: ``data/<rig>/heldout/corpus.parquet``, their own stage's)."""
        if split == HELDOUT:
            return self.heldout_folder(rig) / "corpus.parquet"
        return self.rig_data(rig) / "corpus" / f"{_split(split)}.parquet"

    def heldout_folder(self, rig: str) -> Path:
        """The held-out takes and their poses: ``data/<rig>/heldout/``."""
        return self.rig_data(rig) / HELDOUT

    def corpus_folder(self, rig: str) -> Path:
        return self.rig_data(rig) / "corpus"

    def poses(self, rig: str, split: str) -> Path:
        """The rig evaluated on a split's frames: ``data/<rig>/poses/<split>.parquet``
        (held-out takes: ``data/<rig>/heldout/poses.parquet``)."""
        if split == HELDOUT:
            return self.heldout_folder(rig) / "poses.parquet"
        return self.rig_data(rig) / "poses" / f"{_split(split)}.parquet"

    def poses_folder(self, rig: str) -> Path:
        return self.rig_data(rig) / "poses"

    def params_stamp(self) -> Path:
        """What the check_params stage writes, and every stage reads:
        ``data/params_checked.txt``."""
        return self.data / PARAMS_STAMP

    def samples(self, rig: str, sampler: str) -> Path:
        """A sampler's posed supersamples: ``data/<rig>/samples/<sampler>.npz``."""
        return self.rig_data(rig) / "samples" / f"{sampler}.npz"

    # --- models/<rig>/ -----------------------------------------------------------------
    def rig_models(self, rig: str) -> Path:
        return self.models / rig

    def model(self, rig: str, model_id: ModelId) -> Path:
        """A fitted mapping's folder: ``models/<rig>/<regressor>-<sampler>-<kernel>/``; a
        replicate's network: ``models/seeds/<k>/<rig>/<model id>/`` (outside ``models/<rig>``,
        which seed 0's evaluate stage depends on whole)."""
        if self.replicate is not None and model_id.regressor in REPLICATED_REGRESSORS:
            return self.models / SEEDS / str(self.replicate) / rig / model_id.folder_name
        return self.rig_models(rig) / model_id.folder_name

    # --- metrics/<rig>/<set>/ and reports/ ---------------------------------------------
    def metrics_folder(self, rig: str, metric_set: str) -> Path:
        """One evaluation set's metrics: ``metrics/<rig>/<set>/``; a replicate's:
        ``metrics/<rig>/<set>_seed<k>/``."""
        if self.replicate is not None:
            return self.metrics / rig / replicate_set(metric_set, self.replicate)
        return self.metrics / rig / metric_set

    def metrics_file(self, rig: str, metric_set: str, stem: str) -> Path:
        """One evaluated row's scores: ``metrics/<rig>/<set>/<stem>.json`` (its per-frame
        errors: :func:`per_frame_file`)."""
        return self.metrics_folder(rig, metric_set) / f"{stem}.json"

    # --- one application's folders --------------------------------------------------
    def app_data(self, rig: str, app: str) -> Path:
        """An application's data (``EDITS``: edited clips; ``LATENT``: synthesised clips and
        their log): ``data/<rig>/<app>/``."""
        return self.rig_data(rig) / app

    def app_models(self, rig: str, app: str) -> Path:
        """An application's fitted models: ``models/<rig>/<app>/``."""
        return self.rig_models(rig) / app

    def app_metrics(self, rig: str, app: str) -> Path:
        """An application's metrics: ``metrics/<rig>/<app>/`` (see :meth:`metrics_folder`)."""
        return self.metrics_folder(rig, app)

    def edits_refinement(self, rig: str) -> Path:
        """The edit_add stage's metrics: ``metrics/<rig>/edits/refinement/``."""
        return self.app_metrics(rig, EDITS) / "refinement"

    def latent_fit(self, rig: str) -> Path:
        """The latent stage's GPLVMs (its fit step): ``models/<rig>/latent/fit/``."""
        return self.app_models(rig, LATENT) / "fit"

    def latent_match(self, rig: str) -> Path:
        """The latent stage's transition table (its match step): ``models/<rig>/latent/match/``."""
        return self.app_models(rig, LATENT) / "match"

    def map_model(self, rig: str, subset: str) -> Path:
        """A map subset's model cache: ``models/<rig>/map-<subset>/``."""
        return self.rig_models(rig) / f"{MAP_PREFIX}{subset}"

    def map_data(self, rig: str, stage: str = MAP) -> Path:
        """A map stage's mapped clips: ``data/<rig>/<stage>/<clip>/`` (``map``, ``map_suite``)."""
        return self.rig_data(rig) / _map_stage(stage)

    def map_stage_model(self, rig: str, stage: str = MAP) -> Path:
        """A map stage's own map model, inside its output: ``data/<rig>/<stage>/model/`` (so
        the stages reading ``models/<rig>/`` do not wait for it)."""
        return self.map_data(rig, stage) / MAP_STAGE_MODEL

    def map_metrics(self, rig: str, stage: str = MAP) -> Path:
        """A map stage's scores: ``metrics/<rig>/<stage>/``."""
        return self.metrics_folder(rig, _map_stage(stage))

    def map_partial_metrics(self, rig: str) -> Path:
        """The map_partial stage's tables: ``metrics/<rig>/map_partial/``."""
        return self.metrics_folder(rig, MAP_PARTIAL)

    def map_suite_page(self, rig: str) -> Path:
        """The real-mocap suite's page: ``reports/map_suite/<rig>.md`` (beside the report,
        not in ``reports/tables/``, which the report stage owns whole)."""
        return self.reports / MAP_SUITE / f"{rig}.md"

    @staticmethod
    def user_output(*parts: str) -> Path:
        """A user's own run's folder: ``outputs/<parts>`` (``map/<rig>``, ``edits/<name>``)."""
        return USER_OUTPUTS.joinpath(*parts)

    @staticmethod
    def user_root(root: str) -> Path:
        """Where a user's own run puts the ``paths.<root>`` it writes: ``outputs/<root>``."""
        if root not in ROOTS:
            raise ValueError(f"paths root {root!r} is not one of {', '.join(ROOTS)}")
        return USER_OUTPUTS / root

    def figures(self) -> Path:
        return self.reports / "figures"

    def result_figures(self) -> Path:
        """The report's figures of results: ``reports/figures/results/``."""
        return self.figures() / "results"

    def tables(self) -> Path:
        return self.reports / "tables"

    def index_page(self) -> Path:
        """The report's page: ``reports/index.html``."""
        return self.reports / "index.html"


def per_frame_file(metrics_file: Path) -> Path:
    """A metrics JSON's per-frame errors: ``<rig>/<set>/<stem>.json`` ->
    ``<rig>/per_frame/<set>/<stem>.csv``."""
    metrics_file = Path(metrics_file)
    folder = metrics_file.parent
    return folder.parent / PER_FRAME / folder.name / f"{metrics_file.stem}.csv"


def replicate_set(metric_set: str, replicate: int) -> str:
    """A metrics set's folder name for a replicate seed: ``methods`` -> ``methods_seed1``."""
    check_replicate(replicate)
    return f"{metric_set}_seed{replicate}"


def check_replicate(replicate: object) -> None:
    """``replicate`` is None (seed 0, the committed run) or a seed from 1 to 2**31 - 1."""
    if replicate is None:
        return
    if isinstance(replicate, bool) or not isinstance(replicate, int) or not 1 <= replicate < 2**31:
        raise ValueError(
            f"replicate: expected null or a training seed from 1 to 2147483647 (0 is the "
            f"committed run's seed), got {replicate!r}"
        )


def _map_stage(stage: str) -> str:
    if stage not in (MAP, MAP_SUITE):
        raise ValueError(f"map stage {stage!r} is not one of {MAP}, {MAP_SUITE}")
    return stage


def _split(split: str) -> str:
    if split not in SPLITS:
        raise ValueError(f"split {split!r} is not one of {', '.join((*SPLITS, HELDOUT))}")
    return split
