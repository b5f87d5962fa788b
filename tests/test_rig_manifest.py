"""A rig describes itself in one manifest: every consumer finds a toy rig from it alone."""

from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

from rigmap.animation.library import build_clips, libraries, motion_library
from rigmap.reports.catalog import RIGS, rig_label, rig_rows
from rigmap.retarget import script_for, scripted_rigs
from rigmap.rigs import UnknownRigError, available, load, register
from rigmap.rigs import manifest as manifest_module
from rigmap.rigs.manifest import RigManifest, all_manifests, manifest

TOY_MODULE = '''
import numpy as np

from rigmap.animation.library import Motion, MotionLibrary
from rigmap.rigs import Control, ControlTable, Pose, Rig


class ToyRig(Rig):
    """One hinge: control ``bend`` (radians) swings a 10 cm bone in the x-y plane."""

    def __init__(self, length=10.0):
        self.name = "toy"
        self.length = float(length)
        self.controls = ControlTable([Control("bend", "rotate", 0.0, -1.0, 1.0, True, "arm")])
        self.joint_names = ["base", "tip"]
        self.parents = [-1, 0]

    def _pose(self, Y):
        Y = np.asarray(Y, dtype=np.float64)
        tip = np.stack([np.cos(Y[:, 0]), np.sin(Y[:, 0]), np.zeros(len(Y))], axis=1)
        positions = np.stack([np.zeros((len(Y), 3)), self.length * tip], axis=1)
        return Pose(positions, np.zeros((len(Y), 3)), np.tile(np.eye(3), (len(Y), 1, 1)))


def build_toy(**options):
    return ToyRig(**options)


def _swing(clip):
    clip.key("bend", 1, 0.0)
    clip.key("bend", 13, 0.5)


def _script(scene, cog, cog_rotation):
    pass


LIBRARY = MotionLibrary(
    rig="toy",
    train=(Motion("swing", _swing, "a half-radian swing"),),
    test=(Motion("swing_back", _swing, "the same swing, held out"),),
)
'''


@pytest.fixture
def toy_rig(tmp_path, monkeypatch):
    """``toy_rig_module`` on the path and its manifest registered; both gone afterwards."""
    (tmp_path / "toy_rig_module.py").write_text(textwrap.dedent(TOY_MODULE))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(manifest_module, "_REGISTERED", {})
    toy = RigManifest(
        name="toy",
        factory="toy_rig_module:build_toy",
        label="Toy Hinge",
        library="toy_rig_module",
        script="toy_rig_module:_script",
        view="front",
        report_order=99,
        extra=True,
    )
    register(toy)
    yield toy
    sys.modules.pop("toy_rig_module", None)


def test_a_toy_rig_registered_by_manifest_alone_is_found_everywhere(toy_rig):
    assert "toy" in available()
    rig = load("toy")
    assert rig.name == "toy"
    np.testing.assert_allclose(
        rig.evaluate(np.array([[np.pi / 2]]))[0, 1], [0.0, 10.0, 0.0], atol=1e-12
    )
    assert load({"name": "toy", "length": 2.0}).length == 2.0  # options reach the factory
    # the motion-library lookup
    assert "toy" in libraries()
    assert [m.name for m in motion_library("toy").train] == ["swing"]
    (clip,) = build_clips("toy", "train", seed=0, variation=_nominal())
    assert clip.name == "swing"
    # the script baseline and the catalogue
    assert "toy" in scripted_rigs() and script_for("toy").__name__ == "_script"
    assert rig_label("toy") == "Toy Hinge"
    assert rig_rows()[-1].key == "toy" and rig_rows()[-1].display == "Toy Hinge (extra)"
    assert manifest("toy").view == "front"


def _nominal():
    from rigmap.animation.library import Variation

    return Variation().scaled(0.0)


def test_builtin_manifests_keep_the_catalogue_and_lookups_of_before():
    assert [(r.key, r.label, r.extra) for r in RIGS] == [
        ("quadruped", "Quadruped", False),
        ("biped", "Biped", False),
        ("face", "Face", False),
        ("squirrel", "Squirrel", False),
        ("rigify_wolf", "Rigify Wolf (Blender)", True),
    ]
    assert available() == [
        "arkit_face",  # issue #41: no motion library, no report row of Tables 1-3
        "biped",
        "blend_file",
        "face",
        "quadruped",
        "rigify_human",
        "rigify_wolf",
        "squirrel",
    ]
    assert libraries() == ["biped", "face", "quadruped", "rigify_human", "rigify_wolf", "squirrel"]
    assert scripted_rigs() == ["biped", "quadruped"]
    assert {name: m.view for name, m in all_manifests().items() if m.view != "side"} == {
        "face": "front",
        "arkit_face": "front",
    }


def test_listing_rigs_imports_no_rig_module():
    import subprocess

    code = (
        "import sys; from rigmap.rigs import available; from rigmap.reports.catalog import RIGS;"
        "from rigmap.animation.library import libraries; available(); libraries();"
        "print(sorted(m for m in sys.modules if m.startswith(('rigmap.rigs.characters',"
        "'rigmap.rigs.blender', 'rigmap.animation.library.', 'torch', 'bpy'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "['rigmap.animation.library.clip_builder']"


def test_a_bare_factory_still_registers_and_unknown_names_are_named(monkeypatch):
    monkeypatch.setattr(manifest_module, "_REGISTERED", {})
    built = []
    register("quadruped_copy", lambda: built.append(1) or load("quadruped"))
    assert load("quadruped_copy").name == "quadruped" and built == [1]
    assert rig_label("quadruped_copy") == "quadruped_copy"
    with pytest.raises(UnknownRigError, match=r"unknown rig 'nope'.*quadruped"):
        load("nope")
    with pytest.raises(KeyError, match="no motion library for rig 'quadruped_copy'"):
        motion_library("quadruped_copy")
    with pytest.raises(TypeError, match="needs a factory"):
        register("lonely")
