"""Write ``docs/fault-suite.md``: every case of the fault suite (``tests/test_fault*.py``) with
the bad input it feeds and the message it asserts, grouped by issue #36's categories, and
each trial the issue names pointed to its test.

The cases come from ``pytest --collect-only`` (run in this process); inputs from each case's
parametrize values, messages from the test's source (``assert "..." in ...``, ``match=``,
with the case's parameters filled in). Only the category of each test and the issue's trial
list are written here by hand; a test missing from either map, or a trial pointing to a test
that does not exist, stops the script. ``--check`` exits 1 when the committed page is stale
(``tests/test_docs_fault_suite.py`` runs it).

    python scripts/fault_suite.py            # (re)write docs/fault-suite.md
    python scripts/fault_suite.py --check    # is the committed page current?
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import inspect
import io
import sys
import textwrap
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "fault-suite.md"
PATTERN = "tests/test_fault*.py"
BAR = 170  # issue #36's "Must show": at least this many bad inputs covered

CATEGORIES = {  # issue #36's "Why" headings, then ours for the rest of the suite
    "code": "Code runs from data (and no value reaches a shell)",
    "silent": "Silently wrong results",
    "unbounded": "Unbounded memory, time or waits",
    "traceback": "Tracebacks for expected failures",
    "vague": "Vague errors",
    "litter": "User runs litter the checkout",
    "stale": "Stale committed parameters",
    "kills": "Kills, signals and concurrent writers",
    "other": "Other bad inputs: damaged files and out-of-range values",
    "check": "Controls: good input accepted, planted payload shown live (not bad inputs)",
}
CONTROL = "check"

# Test function (or ``function[id]`` for one case) -> category. New tests must be added here.
TEST_CATEGORY = {
    # tests/test_fault_cli.py
    "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item": "code",
    "test_every_stage_command_is_a_fixed_string_whose_values_are_declared_params": "check",
    "test_placeholders_take_the_matrix_entry_and_params_yaml_values": "check",
    "test_hostile_matrix_value_is_refused_before_any_command": "code",
    "test_placeholder_outside_dvc_says_how_to_run_it": "code",
    "test_committed_params_yaml_is_what_conf_composes": "check",
    "test_stale_params_yaml_fails_the_check": "stale",
    "test_six_writers_of_one_output_folder_each_win_whole": "kills",
    "test_six_writers_of_one_output_file_and_folder_mixed_get_a_clear_error": "kills",
    "test_cli_expected_failure_is_one_line_with_exit_2": "traceback",
    "test_cli_bug_keeps_its_traceback_and_rigmap_debug_shows_expected_ones": "check",
    "test_cli_params_yaml_that_is_a_folder_is_one_line": "traceback",
    "test_learn_stages_are_the_ones_failed_below": "check",
    "test_learn_stage_failure_is_one_line_error_not_runtime_error": "traceback",
    "test_learn_writes_under_outputs_never_into_tracked_folders": "litter",
    "test_user_commands_compose_paths_under_outputs": "litter",
    "test_every_stage_gets_the_config_its_interpolated_command_gave": "check",
    # tests/test_fault_models.py
    "test_the_planted_pickle_runs_when_unpickled": "check",
    "test_latent_models_load_with_the_fitted_numbers_bit_for_bit": "check",
    "test_latent_pickle_planted_as_the_models_payload_is_refused_and_not_run": "code",
    "test_latent_pickle_planted_for_synth_run_is_a_one_line_cli_error": "code",
    "test_latent_old_models_pkl_alone_is_never_read": "code",
    "test_latent_pickle_planted_as_the_transitions_payload_is_refused": "code",
    "test_latent_model_missing_an_array_is_refused": "other",
    "test_latent_model_with_a_wrong_shape_is_refused": "other",
    "test_latent_model_of_another_format_version_is_refused": "other",
    "test_latent_payload_path_leaving_the_model_folder_is_refused": "code",
    "test_edit_model_loads_with_the_fitted_numbers": "check",
    "test_edit_pickle_planted_as_the_model_is_refused_and_not_run": "code",
    "test_edit_model_without_its_json_is_refused": "other",
    "test_edit_model_missing_an_array_or_with_a_wrong_shape_is_refused": "other",
    "test_edit_model_with_an_object_array_is_refused_not_unpickled": "code",
    "test_regression_pickle_planted_as_the_payload_is_refused_and_not_run": "code",
    "test_regression_payload_path_outside_the_folder_is_refused": "code",
    "test_regression_payload_outside_with_its_true_hash_is_never_read": "code",
    "test_regression_payload_symlinked_out_of_the_folder_is_refused": "code",
    "test_pyfunc_model_holds_no_code_and_predicts": "check",
    "test_pyfunc_code_file_added_to_the_folder_is_not_run": "code",
    "test_pyfunc_mlmodel_tampered_to_run_code_is_refused": "code",
    "test_pyfunc_data_path_leaving_the_model_folder_is_refused": "code",
    "test_pyfunc_mapping_payload_path_leaving_the_folder_is_refused": "code",
    "test_map_model_pickle_planted_as_its_payload_is_refused_and_not_run": "code",
    "test_map_model_payload_path_leaving_its_folder_is_refused": "code",
    "test_pyfunc_mlmodel_that_is_not_a_pyfunc_description_is_refused": "other",
    # tests/test_fault_options.py
    "test_map_option_refused": "silent",
    "test_map_option_refused[map_frames_abc]": "vague",
    "test_map_option_refused[map_frames_2.5]": "vague",
    "test_map_non_ascii_path_unquoted_is_told_to_quote_it": "vague",
    "test_map_tracks_file_refused": "vague",
    "test_map_tracks_file_refused[npz_fps_array]": "traceback",
    "test_map_tracks_file_refused[npz_fps_string]": "traceback",
    "test_map_tracks_file_refused[npz_object_positions]": "traceback",
    "test_map_tracks_file_refused[npz_window_past_the_end]": "silent",
    "test_map_npz_beyond_memory_refused": "unbounded",
    "test_map_npz_reads_only_the_frames_mapped": "unbounded",
    "test_map_npz_window_reads_the_same_frames_in_small_blocks": "check",
    "test_map_bvh_5000_deep_hierarchy_parses": "traceback",
    "test_pose_targets_refused": "vague",
    "test_rigs_render_controls_refused": "vague",
    "test_rigs_render_controls_refused[render_controls_value_a_list]": "traceback",
    "test_rigs_render_controls_refused[render_controls_a_list]": "traceback",
    "test_rigs_render_out_folder_refused": "vague",
    "test_rigs_render_random_negative_refused": "vague",
    "test_corpus_show_out_folder_refused": "vague",
    "test_export_blend_torch_rig_refused": "traceback",
    "test_export_blend_folder_refused": "vague",
    "test_fit_override_refused": "vague",
    "test_supersample_beyond_memory_refused": "unbounded",
    "test_edits_option_refused": "traceback",
    "test_edits_option_refused[edits_run_a_string]": "silent",
    "test_edits_option_refused[edits_fit_run_a_string]": "silent",
    "test_edits_option_refused[edits_names_a_string]": "silent",
    "test_synth_script_refused": "unbounded",
    "test_synth_script_refused[synth_idle_frames_abc]": "other",
    "test_synth_script_refused[synth_idle_frames_-3]": "other",
    "test_synth_controller_stops_at_the_cap": "unbounded",
    "test_synth_run_shows_progress": "check",
    # tests/test_faults_dvc_params.py
    "test_shell_syntax_in_params_yaml_never_reaches_a_stage_command": "code",
    "test_a_sound_params_yaml_passes_with_a_stamp_that_never_changes": "check",
    # tests/test_faults_files.py
    "test_intact_samples_file_reads": "check",
    "test_truncated_samples_file_names_the_file": "other",
    "test_bit_flipped_samples_file_names_the_file": "other",
    "test_samples_file_without_an_array_or_meta": "other",
    "test_a_diverging_network_fails_without_a_model": "other",
    "test_network_training_is_bit_identical_in_two_processes": "check",
    "test_a_corrupted_cached_rigify_blend_is_generated_again": "other",
    # tests/test_faults_kills.py, test_faults_model_folder.py, test_faults_models.py
    "test_kill_9_mid_stage_then_rerun_gives_identical_outputs": "kills",
    "test_kill_9_mid_rigmap_map_then_rerun_gives_identical_outputs": "kills",
    "test_a_fit_folder_without_its_placement_is_refused": "other",
    "test_untouched_model_loads_and_predicts": "check",
    "test_tampered_interface_naming_a_module_is_refused_without_importing_it": "code",
    "test_interface_naming_a_stdlib_callable_is_refused": "code",
    "test_payload_path_with_dot_dot_leaving_the_model_folder_is_refused": "code",
    "test_symlink_inside_the_mapping_folder_leading_out_is_refused": "code",
    "test_interface_of_another_format_is_refused": "other",
    # tests/test_faults_refine.py
    "test_an_empty_batch_is_named": "other",
    "test_a_tolerance_that_is_no_number_is_refused": "other",
    "test_a_step_that_cannot_difference_is_refused": "other",
    # tests/test_faults_reproduce.py
    "test_bad_values_are_refused_before_params_yaml_is_written": "other",
    "test_an_unquoted_semicolon_is_refused_by_the_override_grammar": "code",
    "test_good_values_are_written": "check",
    "test_the_cli_prints_the_bad_value_without_a_traceback": "traceback",
    "test_a_signalled_dry_run_puts_params_yaml_back": "kills",
    "test_preflight_passes_on_a_healthy_project": "check",
    "test_closed_port_is_named_at_once": "unbounded",
    "test_hanging_server_fails_within_the_stated_timeout": "unbounded",
    "test_failing_server_is_one_clear_error": "unbounded",
    "test_an_output_folder_that_cannot_be_written_is_named": "other",
    "test_missing_blender_is_named_before_any_stage": "other",
    "test_reproduce_stops_before_dvc_and_keeps_params_yaml": "other",
    "test_reproduce_preflight_lines_then_dvc": "check",
    "test_stages_run_with_pinned_cpu_code_paths": "check",
    "test_stages_run_on_one_thread_unless_the_user_says_otherwise": "check",
    # tests/test_faults_resume.py, test_faults_rigs.py, test_faults_stages.py
    "test_fingerprint_covers_behaviour_not_only_names": "check",
    "test_chunks_posed_by_an_older_rig_version_are_not_reused": "other",
    "test_huge_controls_that_overflow_the_rig_are_named": "other",
    "test_a_blender_rig_with_no_workers_is_refused": "other",
    "test_fit_on_a_damaged_samples_file_names_it": "other",
    "test_a_diverging_fit_saves_no_model": "other",
    # tests/test_faults_tracking.py
    "test_sigterm_ends_the_parent_run_killed": "kills",
    "test_a_normal_error_ends_the_parent_run_failed": "kills",
    "test_a_server_that_stalls_after_health_is_named_in_one_line_after_bounded_retries": (
        "unbounded"
    ),
    "test_bad_request_bounds_are_named": "unbounded",
}

# Issue #36's "Why", one entry per concrete trial: (category, the trial, its test cases).
TRIALS = [
    (
        "code",
        "1. a crafted `models/<rig>/latent/*.pkl` (`synth run … paths.models=<dir>`)",
        [
            "test_latent_pickle_planted_for_synth_run_is_a_one_line_cli_error",
            "test_latent_old_models_pkl_alone_is_never_read",
        ],
    ),
    (
        "code",
        "2. a logged pyfunc model's own `pyfunc_entry.py` run when MLflow loads it",
        [
            "test_pyfunc_code_file_added_to_the_folder_is_not_run",
            "test_pyfunc_mlmodel_tampered_to_run_code_is_refused",
        ],
    ),
    (
        "code",
        '3. `seed: "0; touch X"` in params.yaml under `dvc repro --single-item animate@biped`',
        [
            "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item[--single-item-seed_semicolon]",
            "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item[--single-item-seed_dollar]",
            "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item[--single-item-seed_backticks]",
        ],
    ),
    (
        "code",
        "3. the same under `dvc repro -s`",
        [
            "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item[-s-seed_semicolon]",
            "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item[-s-seed_dollar]",
            "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item[-s-seed_backticks]",
        ],
    ),
    (
        "code",
        '4. a map model\'s `"payload": "../../x.npz"`',
        [
            "test_map_model_payload_path_leaving_its_folder_is_refused",
            "test_regression_payload_outside_with_its_true_hash_is_never_read[payload_dot_dot_x_npz]",
        ],
    ),
    (
        "code",
        '4. an MLflow model\'s `"payload": "../../x.npz"`',
        ["test_pyfunc_mapping_payload_path_leaving_the_folder_is_refused"],
    ),
    (
        "code",
        '4. `"payload": "/etc/passwd"` with its hash (`model_io.read_model_files`)',
        ["test_regression_payload_outside_with_its_true_hash_is_never_read[payload_etc_passwd]"],
    ),
    ("silent", "`map.frames=-5`", ["test_map_option_refused[map_frames_-5]"]),
    ("silent", "`map.first_frame=-100`", ["test_map_option_refused[map_first_frame_-100]"]),
    ("silent", "`map.fps=0`", ["test_map_option_refused[map_fps_0]"]),
    ("silent", "`map.fps=-30`", ["test_map_option_refused[map_fps_-30]"]),
    ("silent", "`edits.run=biped`", ["test_edits_option_refused[edits_run_a_string]"]),
    (
        "unbounded",
        "a synth script `idle: {frames: 10000000}`",
        ["test_synth_script_refused[synth_idle_10M_frames]", "test_synth_run_shows_progress"],
    ),
    (
        "unbounded",
        "a 10 M-frame npz with `map.frames=10` (scaled to 500 000 frames)",
        ["test_map_npz_reads_only_the_frames_mapped", "test_map_npz_beyond_memory_refused"],
    ),
    ("unbounded", "`budget.samples=1000000000`", ["test_supersample_beyond_memory_refused"]),
    (
        "unbounded",
        "a tracking server that answers `/health` and then stalls",
        ["test_a_server_that_stalls_after_health_is_named_in_one_line_after_bounded_retries"],
    ),
    (
        "traceback",
        "`rigmap learn` re-raises each stage's message as a `RuntimeError` (7 trials)",
        ["test_learn_stage_failure_is_one_line_error_not_runtime_error"],
    ),
    (
        "traceback",
        "`IsADirectoryError`",
        ["test_cli_expected_failure_is_one_line_with_exit_2[is_a_directory]"],
    ),
    (
        "traceback",
        "`NotADirectoryError`",
        ["test_cli_expected_failure_is_one_line_with_exit_2[not_a_directory]"],
    ),
    (
        "traceback",
        "`ENOTEMPTY` from two atomic writers finishing together",
        [
            "test_cli_expected_failure_is_one_line_with_exit_2[enotempty]",
            "test_six_writers_of_one_output_folder_each_win_whole",
        ],
    ),
    (
        "traceback",
        "a controls JSON with a list",
        [
            "test_rigs_render_controls_refused[render_controls_value_a_list]",
            "test_rigs_render_controls_refused[render_controls_a_list]",
        ],
    ),
    (
        "traceback",
        "an npz whose `fps` is an array",
        ["test_map_tracks_file_refused[npz_fps_array]"],
    ),
    ("traceback", "a 5 000-deep BVH hierarchy", ["test_map_bvh_5000_deep_hierarchy_parses"]),
    (
        "traceback",
        "`edits add` with `rounds=-1`",
        ["test_edits_option_refused[edits_add_rounds_-1]"],
    ),
    ("traceback", "`edits add` with a NaN weight", ["test_edits_option_refused[edits_weight_nan]"]),
    ("traceback", "`export-blend --rig biped`", ["test_export_blend_torch_rig_refused"]),
    ("vague", "`budget.gpr_points=abc`", ["test_fit_override_refused[fit_gpr_points_abc]"]),
    ("vague", "`seed=-1`", ["test_fit_override_refused[fit_seed_-1]"]),
    ("vague", "`map.frames=abc`", ["test_map_option_refused[map_frames_abc]"]),
    ("vague", "`--random -5`", ["test_rigs_render_random_negative_refused"]),
    ("vague", "a non-ASCII path", ["test_map_non_ascii_path_unquoted_is_told_to_quote_it"]),
    ("vague", "a CSV without a frame rate", ["test_map_tracks_file_refused[csv_without_fps]"]),
    ("vague", "a non-zip `.npz`", ["test_map_tracks_file_refused[npz_not_a_zip]"]),
    ("vague", "a bad JSON targets file", ["test_pose_targets_refused[pose_targets_bad_json]"]),
    ("vague", "a binary targets file", ["test_pose_targets_refused[pose_targets_binary]"]),
    (
        "vague",
        "a directory where a file is expected",
        [
            "test_pose_targets_refused[pose_targets_folder]",
            "test_rigs_render_controls_refused[render_controls_folder]",
        ],
    ),
    (
        "litter",
        "`rigmap learn my.blend` writes data/, models/, metrics/ into the checkout",
        [
            "test_learn_writes_under_outputs_never_into_tracked_folders",
            "test_user_commands_compose_paths_under_outputs",
        ],
    ),
    (
        "stale",
        "the committed params.yaml differs from what conf/ composes",
        [
            "test_stale_params_yaml_fails_the_check",
            "test_committed_params_yaml_is_what_conf_composes",
        ],
    ),
    (
        "kills",
        "a 6-process stress of one atomic output",
        [
            "test_six_writers_of_one_output_folder_each_win_whole",
            "test_six_writers_of_one_output_file_and_folder_mixed_get_a_clear_error",
        ],
    ),
    (
        "kills",
        "kill -9 and rerun of `rigmap map`, `rigmap fit` (the fit stage) and a DVC stage",
        [
            "test_kill_9_mid_rigmap_map_then_rerun_gives_identical_outputs",
            "test_kill_9_mid_stage_then_rerun_gives_identical_outputs",
        ],
    ),
]


# Issue #36's "Must show" zeros: the tests that plant what would show one (each asserts it
# did not happen). Their cases are counted on the page; that they pass is the zero.
MUST_SHOW = {
    "code executions (a planted payload would create a file; the test asserts it does not)": [
        "test_latent_pickle_planted_as_the_models_payload_is_refused_and_not_run",
        "test_latent_pickle_planted_for_synth_run_is_a_one_line_cli_error",
        "test_latent_old_models_pkl_alone_is_never_read",
        "test_latent_pickle_planted_as_the_transitions_payload_is_refused",
        "test_edit_pickle_planted_as_the_model_is_refused_and_not_run",
        "test_edit_model_with_an_object_array_is_refused_not_unpickled",
        "test_regression_pickle_planted_as_the_payload_is_refused_and_not_run",
        "test_pyfunc_code_file_added_to_the_folder_is_not_run",
        "test_pyfunc_mlmodel_tampered_to_run_code_is_refused",
        "test_map_model_pickle_planted_as_its_payload_is_refused_and_not_run",
        "test_tampered_interface_naming_a_module_is_refused_without_importing_it",
    ],
    "shell executions (shell syntax in params.yaml or a stage's matrix value; the file it "
    "would `touch` must not exist), under `dvc repro --single-item` and `-s` included": [
        "test_hostile_seed_in_params_yaml_runs_no_shell_under_dvc_repro_single_item",
        "test_hostile_matrix_value_is_refused_before_any_command",
        "test_shell_syntax_in_params_yaml_never_reaches_a_stage_command",
    ],
    "reads outside a model folder (a payload path or symlink leading out is refused)": [
        "test_latent_payload_path_leaving_the_model_folder_is_refused",
        "test_regression_payload_path_outside_the_folder_is_refused",
        "test_regression_payload_outside_with_its_true_hash_is_never_read",
        "test_regression_payload_symlinked_out_of_the_folder_is_refused",
        "test_pyfunc_data_path_leaving_the_model_folder_is_refused",
        "test_pyfunc_mapping_payload_path_leaving_the_folder_is_refused",
        "test_map_model_payload_path_leaving_its_folder_is_refused",
        "test_payload_path_with_dot_dot_leaving_the_model_folder_is_refused",
        "test_symlink_inside_the_mapping_folder_leading_out_is_refused",
    ],
}


class _Collector:
    """pytest plugin: keeps the items of a ``--collect-only`` run."""

    def __init__(self):
        self.items = []

    def pytest_collection_finish(self, session):
        self.items = list(session.items)


def collect() -> list:
    """The fault suite's test items, as ``pytest --collect-only`` finds them."""
    import pytest

    collector = _Collector()
    files = sorted(str(p) for p in ROOT.glob(PATTERN))
    args = ["--collect-only", "-q", "-p", "no:cacheprovider", f"--rootdir={ROOT}", *files]
    with contextlib.redirect_stdout(io.StringIO()) as output:
        status = pytest.main(args, plugins=[collector])
    if status != 0 or not collector.items:
        print(output.getvalue()[-3000:], file=sys.stderr)
        raise SystemExit(f"fault_suite: collecting {PATTERN} failed (pytest status {status})")
    return collector.items


def _text(node, scope: dict) -> str | None:
    """The string ``node`` evaluates to, as far as the source and ``scope`` tell; f-string
    parts that are not known stay as ``{expression}``."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        parts = []
        for value in node.values:
            if isinstance(value, ast.Constant):
                parts.append(str(value.value))
            elif isinstance(value.value, ast.Name) and value.value.id in scope["params"]:
                known = scope["params"][value.value.id]
                parts.append(repr(known) if value.conversion == ord("r") else str(known))
            else:
                parts.append("{" + ast.unparse(value.value) + "}")
        return "".join(parts)
    if isinstance(node, ast.Name):
        if isinstance(scope["params"].get(node.id), str):
            return scope["params"][node.id]
        if node.id in scope["assigned"]:
            return _text(scope["assigned"][node.id], scope)
        known = scope["globals"].get(node.id)
        return known if isinstance(known, str) else None
    if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name):
        table, key = scope["globals"].get(node.value.id), node.slice
        if isinstance(table, dict) and isinstance(key, ast.Name) and key.id in scope["params"]:
            found = table.get(scope["params"][key.id])
            return found if isinstance(found, str) else None
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        left, right = _text(node.left, scope), _text(node.right, scope)
        return left + right if left is not None and right is not None else None
    return None


def _asserted(node) -> list:
    """The expressions a test asserts a message contains or equals, or matches."""
    found = []
    if isinstance(node, ast.Assert):
        tests = node.test.values if isinstance(node.test, ast.BoolOp) else [node.test]
        for test in tests:
            if isinstance(test, ast.Compare) and isinstance(test.ops[0], ast.In):
                found.append(test.left)
            elif isinstance(test, ast.Compare) and isinstance(test.ops[0], ast.Eq):
                for side in (test.left, test.comparators[0]):  # err == "..." or [...] == lines
                    found += side.elts if isinstance(side, (ast.List, ast.Tuple)) else [side]
    if isinstance(node, ast.Call):
        found += [k.value for k in node.keywords if k.arg == "match"]
    return found


def messages(item) -> list[str]:
    """The messages ``item``'s test asserts, its parameters filled in, in source order."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(item.function)))
    assigned = {
        node.targets[0].id: node.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name)
    }
    params = item.callspec.params if hasattr(item, "callspec") else {}
    scope = {"params": params, "assigned": assigned, "globals": vars(item.module)}
    expressions = sorted(
        (expression for node in ast.walk(tree) for expression in _asserted(node)),
        key=lambda expression: (expression.lineno, expression.col_offset),
    )
    found = []
    for expression in expressions:
        text = _text(expression, scope)
        if text and len(text) > 3 and text not in found:
            found.append(text)
    return found


def _value(value) -> str:
    if isinstance(value, BaseException):
        return f"{type(value).__name__}: {value}".removesuffix(": ")
    if isinstance(value, list):
        return " ".join(map(str, value))
    return str(value) if str(value).strip() else repr(value)


def bad_input(item) -> str:
    """What ``item`` feeds: its parameters (its id where one is code, e.g. a file maker);
    without parameters, its docstring's first paragraph."""
    params = dict(item.callspec.params) if hasattr(item, "callspec") else {}
    if params:
        shown = [v for k, v in params.items() if k not in ("message", "trial")]
        if any(callable(v) for v in params.values()) or not shown:
            return item.callspec.id
        return " ".join(_value(v) for v in shown)
    doc = inspect.getdoc(item.function) or item.originalname[5:].replace("_", " ")
    doc = doc.split("\n\n")[0].replace("\n", " ")
    return doc.removeprefix("Trial: ").removeprefix("Trials: ")


def case_name(item) -> str:
    """``function`` or ``function[id]``: how TEST_CATEGORY and TRIALS name a case."""
    return item.name if hasattr(item, "callspec") else item.originalname


def category(item) -> str:
    found = TEST_CATEGORY.get(case_name(item), TEST_CATEGORY.get(item.originalname))
    if found not in CATEGORIES:
        raise SystemExit(f"fault_suite: {item.nodeid} has no category in TEST_CATEGORY")
    return found


def _cell(text: str) -> str:
    """``text`` as a Markdown table cell in code type (pipes escaped, one line)."""
    text = text.replace("\n", "\\n").replace("|", "\\|")
    fence = "``" if "`" in text else "`"
    return f"{fence} {text} {fence}" if fence == "``" else f"`{text}`"


def _trial_rows(items: list) -> list[str]:
    known = {case_name(item): item for item in items}
    known.update({item.originalname: item for item in items})
    rows = ["| Category | Trial | Test case(s) |", "|---|---|---|"]
    for key, trial, cases in TRIALS:
        missing = [case for case in cases if case not in known]
        if missing:
            raise SystemExit(f"fault_suite: trial {trial!r} points to missing tests {missing}")
        where = "<br>".join(f"`{known[c].path.name}::{c}`" for c in cases)
        rows.append(f"| {CATEGORIES[key].split(' (')[0]} | {trial} | {where} |")
    return rows


def _must_show_lines(items: list) -> list[str]:
    lines = []
    for zero, tests in MUST_SHOW.items():
        missing = [t for t in tests if not any(i.originalname == t for i in items)]
        if missing:
            raise SystemExit(f"fault_suite: MUST_SHOW names tests that do not exist: {missing}")
        cases = [item for item in items if item.originalname in tests]
        lines.append(f"- 0 {zero}: {len(cases)} cases of {len(tests)} tests")
    return lines


def render(items: list) -> str:
    """The page: counts, the issue's trials, then every case by category."""
    names = {case_name(item) for item in items} | {item.originalname for item in items}
    unused = sorted(set(TEST_CATEGORY) - names)
    if unused:
        raise SystemExit(f"fault_suite: TEST_CATEGORY names tests that do not exist: {unused}")
    by_category = {key: [item for item in items if category(item) == key] for key in CATEGORIES}
    bad = sum(len(cases) for key, cases in by_category.items() if key != CONTROL)
    files = Counter(item.path.name for item in items)
    lines = [
        "# The fault suite (issue #36)",
        "",
        "Generated by `python scripts/fault_suite.py` from `pytest --collect-only "
        f"{PATTERN}` and the tables those tests parametrize over; do not edit by hand "
        "(`tests/test_docs_fault_suite.py` fails when this page is stale). Each row is one "
        "test case: the input it feeds and the messages it asserts (from the test's source, "
        "its parameters filled in; `{...}` is a value known only when the test runs).",
        "",
        f"- **{bad} bad inputs and faults** covered (issue #36's bar: at least {BAR}), "
        f"plus {len(by_category[CONTROL])} control cases; {len(items)} test cases in "
        f"{len(files)} files.",
    ]
    lines += [f"- {CATEGORIES[key]}: {len(cases)}" for key, cases in by_category.items()]
    lines += ["", "## Issue #36's must-show zeros", "", *_must_show_lines(items)]
    lines += ["", "## Issue #36's trials and their tests", "", *_trial_rows(items)]
    for key, cases in by_category.items():
        lines += ["", f"## {CATEGORIES[key]} ({len(cases)})", ""]
        lines += ["| Test case | Input | Message(s) asserted |", "|---|---|---|"]
        for item in cases:
            asserted = "<br>".join(_cell(m) for m in messages(item)) or "(the outcome only)"
            name = f"`{item.path.name}::{case_name(item)}`"
            lines.append(f"| {name} | {_cell(bad_input(item))} | {asserted} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the page is stale")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT / "tests"))
    text = render(collect())
    if args.check:
        if not PAGE.is_file() or PAGE.read_text() != text:
            print(f"{PAGE.relative_to(ROOT)} is stale: run python scripts/fault_suite.py")
            return 1
        print(f"{PAGE.relative_to(ROOT)} is current")
        return 0
    PAGE.write_text(text)
    print(f"wrote {PAGE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
