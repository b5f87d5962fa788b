"""dvc.yaml as DVC resolves it: the matrices read conf's lists, a new sampler or rig edits no stage.

The stages are read through DVC's own API (``Repo.index.stages``), so matrices, params
interpolation and YAML merges are expanded exactly as ``dvc repro`` expands them.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir

from rigmap.animation.library import libraries
from rigmap.app.params import compose_params, write_params
from rigmap.app.stage import RIG_OVERRIDES, apply_rig_overrides, stage_config
from rigmap.rigs import available as available_rigs
from rigmap.sampling import available as available_samplers
from rigmap.store.layout import per_frame_file
from rigmap.store.pipeline_files import pipeline_files
from stage_scripts import copy_stage_files

ROOT = Path(__file__).resolve().parents[1]
KERNELS = ["multiquadric", "gaussian", "linear", "polynomial"]


def resolved_stages(project: Path) -> dict:
    """``{"animate@quadruped": stage, ...}`` as DVC builds them from ``project/dvc.yaml``."""
    from dvc.repo import Repo

    with Repo(str(project)) as repo:
        return {stage.name: stage for stage in repo.index.stages}


def filled(stage, project: Path = ROOT) -> str:
    """The stage's command as it runs: its @placeholders filled (rigmap.app.placeholders)."""
    from rigmap.app.placeholders import resolve_argv

    resolved = resolve_argv(stage.cmd.split(), project, stage.name)
    values = [f"{key}={value}" for key, (_, value) in resolved.params.items()]
    return " ".join([*resolved.argv, *values])


def paths(entries) -> list[str]:
    return [entry.def_path for entry in entries]


@pytest.fixture(scope="module")
def stages():
    return resolved_stages(ROOT)


@pytest.fixture(scope="module")
def params():
    return yaml.safe_load((ROOT / "params.yaml").read_text())


def test_params_yaml_is_composed_from_conf():
    """The committed params.yaml is what `rigmap reproduce` / `dvc exp run` would write."""
    assert (ROOT / "params.yaml").read_text() == compose_params(ROOT / "conf")


#: the edit stages' subjects: every subject of conf/edits/default.yaml
EDIT_SUBJECTS = sorted(
    yaml.safe_load((ROOT / "conf/edits/default.yaml").read_text(encoding="utf-8"))["subjects"]
)

#: rigs with a motion library that the quick pipeline leaves out, and why
OUTSIDE_THE_PIPELINE: set[str] = set()


def test_every_rig_with_a_motion_library_is_in_one_family(params):
    with_library = sorted(
        name
        for name in libraries()
        if name in available_rigs() and name not in OUTSIDE_THE_PIPELINE
    )
    pipeline = params["pipeline"]
    own_files = [rig for rig in pipeline["blender_rigs"] if rig.startswith("blend_file:")]
    families = pipeline["rigs"] + pipeline["blender_rigs"] + pipeline["blender_map_rigs"]
    assert sorted(set(families) - set(own_files)) == with_library
    assert pipeline["blender_rigs"] == ["rigify_wolf", *own_files]  # the .blend fixture's corpus
    # rigify_human is only mapped: its fit and Table 1 (~9 min) are over the quick budget
    assert pipeline["blender_map_rigs"] == ["rigify_human"]
    assert set(pipeline["blender_map_rigs"]) <= set(pipeline["map_rigs"])
    assert set(pipeline["table1_rigs"]) <= set(pipeline["rigs"])


def test_the_planned_work_per_stage_kind(stages, params):
    """The 95 stages the hand-written 664-line dvc.yaml planned, counted by kind, plus the
    check_params stage every stage depends on, the mean predictor's fits, the held-out takes
    and their evaluations, the joint-space network's fits and samples sweeps, the
    edit-propagation stage (fit, apply, evaluate) per edits subject,
    the mocap maps, the corpus and poses of the Blender rigs only mapped (rigify_human)
    and the two map_partial stages (issue 14)."""
    edited = sorted(name.split("@")[1] for name in stages if name.startswith("edits@"))
    assert edited == EDIT_SUBJECTS
    rigs, blender = params["pipeline"]["sweep_rigs"], params["pipeline"]["blender_rigs"]
    map_only = params["pipeline"]["blender_map_rigs"]
    table1, seeds = params["pipeline"]["table1_rigs"], len(params["pipeline"]["spread_seeds"])
    mesh, mesh_fit = params["pipeline"]["mesh_table1_rigs"], params["pipeline"]["mesh_fit_rigs"]
    kinds: dict[str, int] = {}
    for name in stages:
        kind = name.split("@")[0].removesuffix("_blender")
        kinds[kind] = kinds.get(kind, 0) + 1
    assert kinds == {
        "check_params": 1,
        "animate": len(params["pipeline"]["rigs"]) + len(blender),
        "pose": len(params["pipeline"]["rigs"]) + len(blender),
        "supersample": 6 * len(rigs) + len(blender),
        "fit_nn": 6 * len(rigs) + len(blender),
        "fit_gpr": 4 * len(rigs) + len(blender),
        "fit_mean": len(params["pipeline"]["table1_rigs"]) + len(blender),
        "heldout": len(params["pipeline"]["table1_rigs"]),
        "evaluate_splits": 2 * len(params["pipeline"]["table1_rigs"]),
        "sample_figures": len(rigs),
        "evaluate": len(table1) + len(blender),
        "evaluate_samplers": len(rigs),
        "evaluate_kernels": len(rigs),
        "sample_sweep": 2,
        "sample_sweep_joint_space": 2,
        "fit_nn_joint_space": 2,
        "report": 1,
        # one per subject conf/edits defines (the motion library, CMU 131, CMU 07 and 08)
        "edits": len(EDIT_SUBJECTS),
        # latent synthesis (issue #18): one stage per rig of latent.rigs (quick: the faces)
        "latent": len(params["latent"]["rigs"]),
        "map_mocap": len(params["pipeline"]["map_rigs"]),
        "map_partial": 2,
        "map_path": 1,  # Fig. 7 on the biped (issue #42)
        "simulate": 1,  # the squirrel simulated in Blender, mapped (Fig. 9, issue #42)
        "map_partial_face": 1,  # FaceIK (Fig. 10, issue #42)
        # the face's and squirrel's Table 1 (issue #42): their fits where no sweep makes them
        **{f"{kind}_mesh": len(mesh_fit) for kind in ("supersample", "fit_nn", "fit_gpr")},
        **{f"{kind}_mesh": len(mesh) for kind in ("fit_mean", "evaluate")},
        "animate_map": len(map_only),
        "pose_map": len(map_only),
        # a user's .blend (issue #19): the file, then the Blender families run it
        "blend_fixture": 1,
        # Table 1's networks per replicate training seed (issue #36): built-in rigs, the
        # Blender rigs (the user's .blend among them); only the network rows evaluated
        "fit_nn_seed": (len(table1) + len(blender)) * seeds,
        "evaluate_seed": (len(table1) + len(blender)) * seeds,
        "fit_nn_joint_space_seed": len(table1) * seeds,
    }
    assert len(stages) == (
        24 + len(EDIT_SUBJECTS) + 2 * len(params["pipeline"]["rigs"]) + 19 * len(rigs)
        + 3 * len(mesh_fit) + 2 * len(mesh)
        + len(params["pipeline"]["map_rigs"]) + 2 * len(map_only) + 7 * len(blender)
        + len(params["latent"]["rigs"])
        + (3 * len(table1) + 2 * len(blender)) * seeds
    )  # fmt: skip
    assert blender == ["rigify_wolf", "blend_file:hero"]


def test_the_latent_stages_run_on_the_face_in_quick_and_add_the_squirrel_in_paper(stages, params):
    """The latent stage (issue #18) runs per rig of latent.rigs: the face, which is no sweep
    rig, and the ARKit face on captured takes (issue #41), in experiment=quick; its four steps
    (no +latent_step: all of them, in order) write under the rig's folders."""
    assert params["latent"]["rigs"] == ["face", "arkit_face"]
    assert "../shared/face" in paths(stages["latent@arkit_face"].deps)  # the captured takes
    assert "face" not in params["pipeline"]["sweep_rigs"]
    latent = stages["latent@face"]
    assert "rig=face" in filled(latent) and "latent_step" not in filled(latent)
    assert {"pipelines/latent.py", "src/rigmap", "conf/latent"} <= set(paths(latent.deps))
    assert "latent.max_iter=100" in filled(latent) and "latent.size=quick" in filled(latent)
    assert {"models/face/latent", "data/face/latent", "reports/figures/latent_face.png"} <= set(
        paths(latent.outs)
    )
    assert [o.def_path for o in latent.outs if o.metric] == ["metrics/face/latent/summary.json"]
    paper = yaml.safe_load(compose_params(ROOT / "conf", ["experiment=paper"]))["latent"]
    assert paper["rigs"] == ["face", "squirrel", "arkit_face"]
    assert paper["max_iter"] == 300 and paper["size"] == "paper"


def test_a_users_blend_runs_through_the_blender_families_by_its_rig_config(stages, params):
    """The fixture is one of the Blender rigs, named by its config (conf/rig/blend_file:hero.yaml
    gives rig=blend_file its path): no stage names the file's path in its command, each
    depends on the file, writes under the rig's name, and the report reads its rows."""
    fixture = "data/blend_fixture/hero.blend"
    assert paths(stages["blend_fixture"].outs) == [fixture]
    hero = "blend_file:hero"
    assert hero in params["pipeline"]["blender_rigs"]
    for name, stage in stages.items():
        if name.endswith(f"@{hero}") or f"@{hero}-" in name:
            assert "rig.path" not in stage.cmd and fixture in paths(stage.deps), name
    assert paths(stages[f"animate_blender@{hero}"].outs) == [f"data/{hero}/corpus"]
    metrics = paths(o for o in stages[f"evaluate_blender@{hero}"].outs if o.metric)
    assert metrics == [f"metrics/{hero}/methods"]
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = apply_rig_overrides(compose(config_name="config", overrides=[f"rig={hero}"]))
    assert (cfg.rig.name, cfg.rig.path, cfg.rig.armature) == ("blend_file", fixture, "rig")
    assert "script" not in cfg.evaluate.methods and cfg.budget.gpr_points == 150  # no retarget map


def test_a_rig_only_mapped_gets_its_corpus_and_poses_and_its_map(stages, params):
    for rig in params["pipeline"]["blender_map_rigs"]:
        animate, pose = stages[f"animate_map_blender@{rig}"], stages[f"pose_map_blender@{rig}"]
        assert paths(animate.outs) == [f"data/{rig}/corpus"] and f"rig={rig}" in filled(animate)
        assert paths(pose.outs) == [f"data/{rig}/poses"]
        assert f"data/{rig}/corpus" in paths(pose.deps)
        mapped = stages[f"map_mocap@{rig}"]
        assert {f"data/{rig}/corpus", f"data/{rig}/poses"} <= set(paths(mapped.deps))
        assert not [name for name in stages if name.startswith(("fit_", "evaluate")) and
                    name.endswith(f"@{rig}")]  # fmt: skip


def test_built_in_rigs_run_every_sampler_and_kernel(stages, params):
    """Every rig of the sweep family: each sampler and kernel; the other built-in rigs get
    their corpus and poses, the latent stages of latent.rigs (issue #18), and Table 1 and
    FaceIK by the mesh family (issue #42: test_the_mesh_rigs_join_table_1_by_a_family_...)."""
    assert set(params["pipeline"]["sweep_rigs"]) <= set(params["pipeline"]["rigs"])
    assert set(params["pipeline"]["table1_rigs"]) <= set(params["pipeline"]["sweep_rigs"])
    for rig in set(params["pipeline"]["rigs"]) - set(params["pipeline"]["sweep_rigs"]):
        assert f"pose@{rig}" in stages
        assert not [name for name in stages if name.endswith((f"@{rig}", f"@{rig}-gmm"))
                    and not name.startswith(("animate@", "pose@", "latent@", "simulate@",
                                             "fit_mean_mesh@",
                                             "evaluate_mesh@", "map_partial_face@"))]  # fmt: skip
    for rig in params["pipeline"]["sweep_rigs"]:
        for sampler in available_samplers():
            supersample = stages[f"supersample@{rig}-{sampler}"]
            assert paths(supersample.outs) == [f"data/{rig}/samples/{sampler}.npz"]  # no chunks
            assert f"sampler={sampler}" in filled(supersample)
            fit = stages[f"fit_nn@{rig}-{sampler}"]
            assert f"data/{rig}/samples/{sampler}.npz" in paths(fit.deps)
            assert paths(fit.outs) == [f"models/{rig}/nn-{sampler}-none"]
        for kernel in KERNELS:
            fit = stages[f"fit_gpr@{rig}-{kernel}"]
            assert paths(fit.outs) == [f"models/{rig}/gpr-none-{kernel}"]
        figure = stages[f"sample_figures@{rig}"]
        assert f"data/{rig}/samples" in paths(figure.deps)
        assert [(o.def_path, o.use_cache) for o in figure.outs] == [
            (f"reports/figures/samples_{rig}.png", False)  # committed to git for the README
        ]
        for stage in (f"animate@{rig}", f"pose@{rig}", f"supersample@{rig}-gmm"):
            assert f"conf/rig/{rig}.yaml" in paths(stages[stage].deps)


def test_the_mesh_rigs_join_table_1_by_a_family_of_their_own(stages, params):
    """The face and the squirrel in Table 1 (issue #42): the network and GPR of Table 1 fitted
    where no sweep fits them (experiment=quick), the mean predictor, and the evaluation with
    the methods their rig configs name; in experiment=paper the sweeps fit them instead."""
    mesh, mesh_fit = params["pipeline"]["mesh_table1_rigs"], params["pipeline"]["mesh_fit_rigs"]
    assert mesh == mesh_fit == ["face", "squirrel"]
    assert not set(mesh) & set(params["pipeline"]["sweep_rigs"])
    for rig in mesh:
        assert paths(stages[f"supersample_mesh@{rig}-pca_gaussian"].outs) == [
            f"data/{rig}/samples/pca_gaussian.npz"
        ]
        assert paths(stages[f"fit_nn_mesh@{rig}-pca_gaussian"].outs) == [
            f"models/{rig}/nn-pca_gaussian-none"
        ]
        gpr = stages[f"fit_gpr_mesh@{rig}-multiquadric"]
        assert paths(gpr.outs) == [f"models/{rig}/gpr-none-multiquadric"]
        assert filled(gpr) == filled(stages["fit_gpr@biped-multiquadric"]).replace("biped", rig)
        assert paths(stages[f"fit_mean_mesh@{rig}"].outs) == [f"models/{rig}/mean-none-none"]
        evaluate = stages[f"evaluate_mesh@{rig}"]
        assert evaluate.cmd == stages["evaluate@biped"].cmd
        assert f"models/{rig}" in paths(evaluate.deps)
        assert [o.def_path for o in evaluate.outs if o.metric] == [f"metrics/{rig}/methods"]
        with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
            cfg = apply_rig_overrides(compose(config_name="config", overrides=[f"rig={rig}"]))
        methods = list(cfg.evaluate.methods)
        assert "script" not in methods and not [m for m in methods if "joint_space" in m]
        assert {"gpr", "nn", "nn_computed_jacobian", "mean"} <= set(methods)
        assert cfg.evaluate.frames_per_clip is None  # whole test clips
    face = stages["map_partial_face@face"]
    assert face.cmd == stages["map_partial@biped"].cmd
    assert [o.def_path for o in face.outs if o.metric] == [
        "metrics/face/map_partial/partial_inputs.json"
    ]
    paper = yaml.safe_load(compose_params(ROOT / "conf", ["experiment=paper"]))["pipeline"]
    assert paper["mesh_fit_rigs"] == [] and set(paper["mesh_table1_rigs"]) <= set(
        paper["sweep_rigs"]
    )  # the paper's sweeps fit their models: no output made by two stages


def test_the_blender_family_runs_table_1_only(stages):
    wolf = "rigify_wolf"
    for stage in (f"animate_blender@{wolf}", f"pose_blender@{wolf}"):
        assert "src/rigmap" in paths(stages[stage].deps)
    assert paths(stages[f"supersample_blender@{wolf}-pca_gaussian"].outs) == [
        f"data/{wolf}/samples/pca_gaussian.npz"
    ]
    assert f"fit_nn_blender@{wolf}-pca_gaussian" in stages
    assert f"fit_gpr_blender@{wolf}-multiquadric" in stages
    evaluate = stages[f"evaluate_blender@{wolf}"]
    # the same command as the built-in rigs': methods and budgets come from the rig's
    # _overrides_ (test_the_wolf_budget_comes_from_its_rig_config_over_the_command_line)
    assert evaluate.cmd == stages["evaluate@biped"].cmd
    assert [o.def_path for o in evaluate.outs if o.metric] == [f"metrics/{wolf}/methods"]
    assert all(not o.use_cache for o in evaluate.outs)


@pytest.mark.parametrize(
    "name",
    [
        "evaluate@quadruped",
        "evaluate_blender@rigify_wolf",
        "evaluate_blender@blend_file:hero",
        "evaluate_splits@biped-heldout",
        "evaluate_samplers@biped",
        "evaluate_kernels@biped",
    ],
)
def test_evaluations_declare_metrics_and_per_frame_plots_as_folders(stages, name):
    """One metrics folder (the JSONs) and one plots folder (the per-frame CSVs) a stage, the
    folder the evaluation writes each JSON's CSV to: a new method or sampler is tracked with
    no stage edited, and DVC never reads a CSV as metrics."""
    stage = stages[name]
    metrics = [o.def_path for o in stage.outs if o.metric]
    plots = [o.def_path for o in stage.outs if o.plot]
    assert len(metrics) == len(plots) == 1
    written = per_frame_file(Path(metrics[0]) / "gpr-none.json")
    assert written.parent.as_posix() == plots[0] and written.suffix == ".csv"
    assert all(not o.use_cache for o in stage.outs)


def test_evaluate_depends_on_its_models_and_the_report_on_everything(stages):
    assert "models/quadruped" in paths(stages["evaluate@quadruped"].deps)
    report = stages["report"]
    assert {"metrics", "data", "conf"} <= set(paths(report.deps))


def test_only_the_report_depends_on_the_lists_of_rigs(stages):
    """Adding a rig to conf/pipeline/ re-runs that rig's stages and the report, no other."""
    for name, stage in stages.items():
        if name == "report":
            continue
        for dep in paths(stage.deps):
            assert dep != "conf" and not dep.startswith("conf/pipeline"), (name, dep)


def test_the_wolf_budget_comes_from_its_rig_config_over_the_command_line():
    """fit_gpr_blender passes params.yaml's gpr_points (250); the rig's _overrides_ win (150)."""
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=["rig=rigify_wolf", "regressor=gpr",
                                                       "budget.gpr_points=250"])  # fmt: skip
        built_in = compose(config_name="config", overrides=["rig=biped", "regressor=gpr"])
    apply_rig_overrides(cfg)
    assert cfg.budget.gpr_points == 150 and cfg.regressor.n_points == 150
    assert cfg.evaluate.frames_per_clip == 12
    assert "nn_autodiff_jacobian" not in cfg.evaluate.methods
    assert RIG_OVERRIDES not in cfg.rig
    assert apply_rig_overrides(built_in).budget.gpr_points == 250  # experiment=quick's
    assert "pipeline" in built_in and "pipeline" not in stage_config(built_in)  # dvc.yaml's lists


def test_a_new_sampler_and_rig_need_no_stage_edit(tmp_path):
    """One yaml for the sampler, names in the conf lists: DVC plans its stages unchanged."""
    project = tmp_path / "project"
    project.mkdir()
    shutil.copytree(ROOT / "conf", project / "conf")
    copy_stage_files(project)
    shutil.copy(ROOT / "conf" / "sampler" / "uniform.yaml", project / "conf/sampler/toy.yaml")
    config = project / "conf" / "pipeline" / "default.yaml"
    rigs = "rigs: [quadruped, biped, face, squirrel"
    config.write_text(config.read_text().replace(rigs, f"{rigs}, toy_rig"))
    quick = project / "conf" / "experiment" / "quick.yaml"  # the sweeps' rigs in the quick run
    sweep = "sweep_rigs: [quadruped, biped"
    quick.write_text(quick.read_text().replace(sweep, f"{sweep}, toy_rig"))
    evaluate = project / "conf" / "evaluate" / "default.yaml"
    evaluate.write_text(
        evaluate.read_text().replace("gmm, pca_gaussian]", "gmm, pca_gaussian, toy]")
    )
    write_params(project, defaults=False)
    subprocess.run(
        [sys.executable, "-m", "dvc", "init", "--no-scm", "-q"],
        cwd=project,
        check=True,
        timeout=120,
    )
    stages = resolved_stages(project)
    for path in pipeline_files(ROOT):  # no stage file edited
        assert (project / path).read_text() == (ROOT / path).read_text()
    assert paths(stages["supersample@quadruped-toy"].outs) == ["data/quadruped/samples/toy.npz"]
    assert "sampler=toy" in filled(stages["fit_nn@biped-toy"], project)
    assert "conf/rig/toy_rig.yaml" in paths(stages["animate@toy_rig"].deps)
    assert "fit_gpr@toy_rig-linear" in stages and "supersample@toy_rig-toy" in stages
    assert "supersample_blender@rigify_wolf-toy" not in stages
