"""The Hydra rig configs of the Blender rigs say what the code's presets say (no Blender needed)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rigmap.rigs.blender.rig import select_names, soft_range_overrides
from rigmap.rigs.blender.rigify import RIGIFY_HUMAN, RIGIFY_WOLF

CONF = Path(__file__).resolve().parents[1] / "conf" / "rig"


@pytest.mark.parametrize(
    ("name", "preset"), [("rigify_human", RIGIFY_HUMAN), ("rigify_wolf", RIGIFY_WOLF)]
)
def test_yaml_matches_the_preset(name, preset):
    config = yaml.safe_load((CONF / f"{name}.yaml").read_text())
    config.pop("_overrides_", None)  # the stage budgets a slow rig sets (rigmap.stage)
    assert config == {"name": name, **preset}


def test_used_selection_globs_and_excludes():
    names = ["hand_ik.L.tx", "hand_ik.R.tx", "hand_ik.L.sx", "torso.IK_FK", "chin.rx"]
    picked = select_names(
        names, {"include": ["hand_ik.[LR].t[xyz]", "torso.*"], "exclude": ["*.R.*"]}, "test"
    )
    assert picked == [True, False, False, True, False]
    assert select_names(names, None, "test") == [True] * 5


def test_used_pattern_that_matches_nothing_is_an_error():
    with pytest.raises(ValueError, match=r"\['hnd_ik\.\*'\] match no name"):
        select_names(["hand_ik.L.tx"], ["hnd_ik.*"], "rig 'x' used")
    with pytest.raises(ValueError, match="unknown keys"):
        select_names(["a"], {"includ": ["a"]}, "rig 'x' used")


def test_soft_ranges_widen_chosen_controls_and_refuse_bad_ones():
    names = ["root.tx", "root.ty", "torso.tz", "foot_ik.L.tx"]
    defaults = [0.0, 0.0, 0.0, 0.0]
    chosen = soft_range_overrides(
        names, defaults, {"root.t[xy]": [-400, 400], "*.t[xz]": [-80, 80]}, "rig 'x' soft_ranges"
    )
    # later patterns win: root.tx is matched by both
    assert chosen == {0: (-80.0, 80.0), 1: (-400.0, 400.0), 2: (-80.0, 80.0), 3: (-80.0, 80.0)}
    assert soft_range_overrides(names, defaults, None, "x") == {}
    with pytest.raises(ValueError, match=r"pattern 'hips\.\*' matches no control"):
        soft_range_overrides(names, defaults, {"hips.*": [-1, 1]}, "x")
    with pytest.raises(ValueError, match=r"leaves out the default 5 of control 'torso\.tz'"):
        soft_range_overrides(names, [0, 0, 5, 0], {"torso.tz": [-1, 1]}, "x")
    with pytest.raises(ValueError, match="needs finite lower < upper"):
        soft_range_overrides(names, defaults, {"root.tx": [3, -3]}, "x")
    with pytest.raises(ValueError, match=r"needs \[lower, upper\] numbers"):
        soft_range_overrides(names, defaults, {"root.tx": "wide"}, "x")
