"""The biped's held-out clips are motions its edit examples never play (issue #40, item 5)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rigmap.edits.representation import TargetError
from rigmap.edits.study import load_study

ROOT = Path(__file__).resolve().parents[1]
SPEC = yaml.safe_load((ROOT / "conf/edits/default.yaml").read_text())["subjects"]["biped"]


def test_the_held_out_motions_are_none_of_the_examples():
    study = load_study("biped", SPEC)
    examples = {c["clip"] for c in SPEC["train"]}
    held_out = [c.track.source.removesuffix(" (seed 1)") for c in study.heldout]
    assert held_out == SPEC["heldout_motions"] and len(held_out) == 10
    assert not examples & set(held_out)
    assert "Walk Start Stop" in held_out  # walking among them, in a motion never shown


@pytest.mark.parametrize("motions", [["Moonwalk"], []])
def test_an_unknown_held_out_motion_is_named(motions):
    spec = {**SPEC, "heldout_motions": motions}
    with pytest.raises(TargetError, match=r"heldout_motions \[.*\] are not motions of its library"):
        load_study("biped", spec)
