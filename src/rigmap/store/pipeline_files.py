"""The pipeline's stage files: the root ``dvc.yaml`` and one ``stages/<family>/dvc.yaml`` each.

DVC rewrites a dvc.yaml's whole ``dvc.lock`` (a round-trip YAML parse and dump) after every
stage it runs; with all 121 stages in one file that rewrite took 3-5 s of each stage's time,
while the repository lock was held. The stages are therefore split over small files, every
stage running from the project root (``wdir: ../..``), and DVC names a stage outside the
root file ``stages/<family>/dvc.yaml:<name>``. rigmap's own readers (matrix placeholders,
the params check, the scheduler's ``meta``, the preflight) read the stage definitions here,
by the short name, so a family's file is a detail of where its text lives.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT_FILE = "dvc.yaml"
STAGE_FILES = "stages/*/dvc.yaml"


class PipelineFileError(ValueError):
    """A stage file cannot be read, or two files define the same stage family."""


@dataclass(frozen=True)
class StageFamily:
    """One key of a ``stages:`` mapping (a stage, or a matrix of them) and its file."""

    name: str
    body: Mapping[str, Any]
    file: Path  # relative to the project

    def address(self, stage: str) -> str:
        """How DVC names ``stage`` (this family's, ``name@key``) on its command line."""
        return stage if self.file.as_posix() == ROOT_FILE else f"{self.file.as_posix()}:{stage}"


def pipeline_files(project: str | Path) -> list[Path]:
    """The project's stage files, relative to it: ``dvc.yaml`` first, then ``stages/*``."""
    project = Path(project)
    found = [Path(ROOT_FILE)] if (project / ROOT_FILE).is_file() else []
    return found + sorted(path.relative_to(project) for path in project.glob(STAGE_FILES))


def pipeline_text(project: str | Path) -> str:
    """Every stage file's text, one after another (for what the commands name)."""
    project = Path(project)
    return "\n".join(
        (project / path).read_text(encoding="utf-8") for path in pipeline_files(project)
    )


def stage_families(project: str | Path) -> dict[str, StageFamily]:
    """Every stage family of every stage file, by name (YAML anchors resolved per file)."""
    import yaml

    project = Path(project)
    families: dict[str, StageFamily] = {}
    for path in pipeline_files(project):
        try:
            text = (project / path).read_text(encoding="utf-8")
            stages = (yaml.safe_load(text) or {}).get("stages") or {}
        except (OSError, yaml.YAMLError, AttributeError) as error:
            raise PipelineFileError(f"{path}: not a readable stage file ({error})") from None
        for name, body in stages.items():
            if name in families:
                raise PipelineFileError(
                    f"{path}: stage {name!r} is already defined in {families[name].file}"
                )
            families[name] = StageFamily(name, body if isinstance(body, Mapping) else {}, path)
    return families


def short_name(address: str) -> str:
    """``stages/fit/dvc.yaml:fit_nn@biped-gmm`` -> ``fit_nn@biped-gmm`` (DVC's names)."""
    head, colon, tail = address.partition(".yaml:")
    return tail if colon and "@" not in head else address


def family_of(stage: str) -> str:
    """``evaluate@quadruped`` (or its file's address) -> ``evaluate``."""
    return short_name(stage).split("@", 1)[0]
