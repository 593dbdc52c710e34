"""`make mutation`: mutmut 3 over every module of nuparquet, one group of modules at a time, each against only
the fast test files that exercise it, within a time budget per group; and the hand-made mutants mutmut does not
make (`--hand`, mutation/hand.py).

    python mutation/run.py                      # every group, the default budget each
    python mutation/run.py geometry mosaic      # some groups
    python mutation/run.py --budget-s 600 projection
    python mutation/run.py geometry --again 'nuparquet.geometry.x_slerp_amount*'   # re-run some mutants
    python mutation/run.py reader builders --sample 300 --seed 0                  # a random sample of each group
    python mutation/run.py map --recheck 'nuparquet.map.queries.x*'               # survivors against every test
    python mutation/run.py --hand engine map                                      # the hand mutants of groups

Every module of nuparquet/ belongs to exactly one group (GROUPS; tests/test_mutation_groups.py checks it), but a
package's `__init__.py` that defines no function or class (`nothing_to_mutate`). Each group runs in its own staging
copy (`.mutation/<group>/`: the package, tests, schemas and a pyproject.toml whose [tool.mutmut] names the group's
modules and tests), so groups never share mutmut state. Generated test datasets are made once for all mutants
(NUPARQUET_TEST_CACHE, see tests/conftest.py), and so are conversions for the groups no conversion runs
(`Group.cache_conversions`). When a budget runs out, mutmut is stopped; the mutants it finished keep their results.
Each group ends with mutmut's own figures (`export-cicd-stats`) and the list of surviving mutants, printed and
written to `.mutation/<group>/survivors.txt`. `mutation/report.py` makes MUTATION.md's figures from them.
"""

from __future__ import annotations

import argparse
import ast
import difflib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
STAGING = REPO / ".mutation"
MUTMUT = [sys.executable, "-m", "mutmut"]

# Every group forks its mutants from a fork server that never ran a test: a process forked while a thread pool
# (DuckDB's in conversions, polars' or numpy's after mutmut's stats pass) holds a lock can hang on it (geometry's
# mutants hung in `interp_two_points` when forked from mutmut's own process).


@dataclass(frozen=True)
class Group:
    """One mutation group: the modules it mutates and the fast tests that exercise them.

    modules: glob patterns relative to the repository (`*` stays inside a folder, `**` goes down); a pattern
        starting with `!` takes modules out again. Every module of nuparquet/ is in exactly one group
        (`tests/test_mutation_groups.py`), except those `nothing_to_mutate` names.
    tests: pytest arguments: test files or node ids.
    marks, keyword: pytest's `-m` and `-k` (browser tests drive Chromium: never; the real extract's conversion is
        ~10 s in every mutant's process: only where a group needs it).
    cache_conversions: the session's converted datasets are made once, by mutmut's unmutated stats pass, and
        reused by every mutant (`NUPARQUET_TEST_CACHE_CONVERSIONS`, tests/conftest.py): only for groups whose
        modules no conversion runs (checked by tests/test_mutation_groups.py against the import graph).
    cache_data: the generated dataroots are made once (`NUPARQUET_TEST_CACHE`); off for the generator's own group.
    serial_engine: the process-pool engine runs its units in the test's process (`NUPARQUET_TEST_SERIAL_ENGINE`,
        tests/conftest.py): mutmut sees only what runs in that process. Off for the engine's own group.
    not_mutated: modules of the group mutmut must leave alone (its `do_not_mutate`): numba compiles their functions
        at run time (`numba.njit(project_pairs)`), and mutmut's trampoline around a function cannot be compiled, so
        the unmutated tests would fail. Their hand-made mutants (mutation/hand_mutants.toml) stand in.
    """

    modules: tuple[str, ...]
    tests: tuple[str, ...]
    marks: str = "not real and not browser"
    keyword: str | None = None
    cache_conversions: bool = False
    cache_data: bool = True
    serial_engine: bool = True
    not_mutated: tuple[str, ...] = ()

    def pytest_args(self) -> list[str]:
        return [*self.tests, "-m", self.marks, *(["-k", self.keyword] if self.keyword else [])]


def _box_projection_small_tests() -> tuple[str, ...]:
    return tuple(f"tests/parity/test_box_projection.py::{name}" for name in (  # the small get_boxes tables
        "test_sweep_box_is_interpolated_for_instances_in_both_samples_and_dropped_when_only_in_previous",
        "test_sweep_time_is_clamped_to_the_two_samples",
        "test_keyframe_and_first_sample_sweep_use_their_sample_boxes_unchanged",
        "test_duplicate_instance_in_previous_sample_gives_one_box_from_the_last_like_devkit_dict"))


GROUPS: dict[str, Group] = {
    # --- the groups of the first runs (2026-11-24/25), grown to hold their packages' other modules -------------
    "geometry": Group(
        ("nuparquet/geometry/*.py",),
        ("tests/parity/test_geometry_math.py", "tests/test_geometry_contract.py", "tests/test_camera.py",
         "tests/test_box_projection_kernel.py",
         "tests/parity/test_points_queries_devkit.py::test_points_in_boxes_equal_devkit_and_num_lidar_pts_on_synthetic_data",
         "tests/conversion/test_truckscenes.py::test_closest_pose_is_the_devkits_getclosest_with_its_ties",
         *_box_projection_small_tests()),
        not_mutated=("nuparquet/geometry/compiled.py",)),
    "projection": Group(
        ("nuparquet/frames/projection.py", "nuparquet/frames/points_in_image.py", "nuparquet/frames/poses.py",
         "nuparquet/frames/boxes.py", "nuparquet/frames/sensor_boxes.py"),
        # the irregular fixture holds every case of the regular one and more: [synth] is left out
        ("tests/parity/test_box_projection.py", "tests/rendering/test_render.py", "tests/test_projection_contract.py",
         "tests/parity/test_dataset_boxes.py"),
        keyword="irregular or not synthetic"),
    "reader": Group(
        ("nuparquet/sources/tables.py", "nuparquet/sources/table_typing.py", "nuparquet/sources/table_scan.py",
         "nuparquet/sources/integrity.py", "nuparquet/sources/json_scan.py", "nuparquet/sources/table_layouts.py"),
        ("tests/conversion/test_bad_input.py", "tests/sources/test_json_records.py",
         "tests/conversion/test_real_layouts.py", "tests/conversion/test_timestamp_units.py",
         "tests/sources/test_scanner.py", "tests/sources/test_tables.py", "tests/sources/test_numeric_lists.py"),
        keyword="not successful_overwrite"),
    "builders": Group(
        ("nuparquet/conversion/builders/annotations.py", "nuparquet/conversion/builders/scenes.py",
         "nuparquet/conversion/builders/instances.py", "nuparquet/conversion/builders/frames.py",
         "nuparquet/conversion/builders/common.py"),
        # the irregular fixture only: it holds the regular one's cases and more, and the real extract's devkit
        # load would add ~3 s to every mutant
        ("tests/parity/test_derived_datasets.py", "tests/conversion/test_empty_annotations.py",
         "tests/conversion/test_real_layouts.py::test_lyft_frames_give_non_images_zero_size_and_annotations_no_visibility",
         "tests/conversion/test_real_layouts.py::test_t4_visibility_comes_from_the_table_and_extra_tables_are_kept"),
        keyword="not synth and not extract"),
    "mosaic": Group(
        ("nuparquet/rendering/plan.py", "nuparquet/rendering/mosaic.py"),
        ("tests/rendering/test_plan.py", "tests/parity/test_mosaic_devkit.py", "tests/rendering/test_render.py"),
        keyword="(mosaic or plan or keyframe) and not 12.0 and not 2.0", cache_conversions=True),
    "video": Group(
        ("nuparquet/rendering/video/video.py",),
        ("tests/rendering/test_video_content.py",
         "tests/rendering/test_video.py::test_video_writer_rejects_frames_of_another_size",
         "tests/rendering/test_video.py::test_video_writer_pads_odd_sizes_and_writes_browser_playable_h264"),
        keyword="not rendered_video"),
    # --- the rest of the package (issue 29) --------------------------------------------------------------------
    "root": Group(  # the small facts and helpers every layer uses
        ("nuparquet/*.py", "!nuparquet/atomic.py"),
        ("tests/test_channels.py", "tests/test_columns.py", "tests/test_schemas.py", "tests/test_schema_types.py",
         "tests/conversion/test_progress.py", "tests/cli/test_option_errors.py", "tests/dataset/test_dataset_api.py",
         "tests/parity/test_dataset_boxes.py", "tests/test_architecture.py", "tests/test_problems.py"),
        keyword="not 300_lines"),  # mutmut's trampolines make every module longer
    "engine": Group(
        ("nuparquet/engine/*.py", "nuparquet/atomic.py"),
        ("tests/engine/test_engine.py", "tests/test_atomic.py", "tests/rendering/test_faults.py",
         # the many-scene render writes its summary through engine.scene_files (without Ray: a session each)
         *(f"tests/rendering/test_scale_out.py::{name}" for name in (
             "test_scenes_and_where_select_the_scenes_rendered",
             "test_unknown_scene_or_bad_where_is_refused_before_any_work",
             "test_resume_after_a_stopped_run_reuses_the_scenes_it_finished",
             "test_resume_renders_again_scenes_made_with_other_options",
             "test_a_second_run_keeps_the_summary_entries_of_scenes_it_did_not_render_and_ignores_a_broken_summary",
             "test_the_many_scene_progress_counts_scenes_under_the_jobs_name"))),
        serial_engine=False),
    "can_bus": Group(
        ("nuparquet/can_bus/*.py", "nuparquet/sources/can_bus.py", "nuparquet/conversion/builders/can_bus.py",
         "nuparquet/conversion/builders/sample_can_bus.py"),
        ("tests/can_bus/", "tests/parity/test_can_bus_devkit.py"),
        keyword="not extract"),
    "map": Group(
        ("nuparquet/map/*.py", "nuparquet/sources/map_expansion.py", "nuparquet/conversion/builders/map_expansion.py"),
        ("tests/map/", "tests/parity/test_map_devkit.py"),
        keyword="not extract"),
    "points": Group(
        ("nuparquet/sources/points.py", "nuparquet/sources/point_layout.py", "nuparquet/conversion/scene_points.py",
         "nuparquet/conversion/builders/points.py", "nuparquet/frames/points.py", "nuparquet/frames/sweeps.py"),
        ("tests/conversion/test_points.py", "tests/parity/test_points_devkit.py", "tests/parity/test_sweeps_devkit.py",
         "tests/conversion/test_progress.py::test_the_total_is_set_once_and_reached_with_points_of_every_scene"),
        keyword="not extract"),
    "sources": Group(  # the JSON records beside the table reader, and dangling references
        ("nuparquet/sources/json_records.py", "nuparquet/sources/json_layout.py", "nuparquet/sources/dangling.py"),
        ("tests/sources/test_json_records.py", "tests/sources/test_json_layout.py",
         "tests/conversion/test_bad_input.py"),
        keyword="not extract"),
    "conversion": Group(
        ("nuparquet/conversion/*.py", "!nuparquet/conversion/scene_points.py"),
        ("tests/conversion/test_convert.py", "tests/conversion/test_registry.py", "tests/conversion/test_progress.py",
         "tests/conversion/test_environment_faults.py", "tests/conversion/test_generality.py", "tests/test_atomic.py",
         # `validate(allow_dangling=True)` in the test's process (the CLI's validate runs in a subprocess)
         "tests/conversion/test_bad_input.py::"
         "test_allow_dangling_warns_of_each_dangling_reference_and_count_by_file_record_and_token"),
        keyword="not extract"),
    "export": Group(
        ("nuparquet/export/*.py",),
        ("tests/sources/test_json_layout.py", "tests/conversion/test_convert.py",
         "tests/parity/test_can_bus_devkit.py::test_export_json_writes_every_can_bus_file_back_exactly"),
        keyword="not extract"),
    "dataset": Group(
        ("nuparquet/dataset/*.py",),
        ("tests/dataset/test_dataset_api.py", "tests/dataset/test_dataset.py", "tests/cli/test_sql_safety.py"),
        cache_conversions=True),
    "queries": Group(
        ("nuparquet/queries/*.py",),
        ("tests/queries/",),
        keyword="not extract", cache_conversions=True),
    "rendering": Group(  # the scene render: the frame loop, tiles, overlays, sinks
        ("nuparquet/rendering/*.py", "nuparquet/rendering/video/*.py", "!nuparquet/rendering/plan.py",
         "!nuparquet/rendering/mosaic.py", "!nuparquet/rendering/video/video.py", "!nuparquet/rendering/map_canvas.py"),
        ("tests/rendering/test_render.py", "tests/rendering/test_bev.py", "tests/rendering/test_frame_index.py",
         "tests/rendering/test_lidar_colors.py", "tests/rendering/test_lidar_predictions.py",
         "tests/rendering/test_predictions.py",
         "tests/rendering/test_pipeline.py", "tests/rendering/test_rigs.py", "tests/rendering/test_video.py",
         "tests/rendering/test_decode.py", "tests/rendering/test_legend.py", "tests/rendering/test_loop.py",
         "tests/rendering/test_colorings.py",
         # the camera tiles of an output that embeds its images; the legend's classes (point_colors.py is here)
         "tests/dataset/test_embedded_sensors.py::test_pictures_a_video_and_an_mcap_export_without_a_dataroot_equal_those_from_files",
         "tests/parity/test_single_renders_devkit.py::test_point_colours_and_legend_classes_are_the_devkits",
         # ImageOptions.check (image_options.py is this group's) refuses a map picture without --map here
         "tests/rendering/test_single_cli.py::test_what_cannot_be_drawn_is_a_usage_error"),
        keyword="not extract", cache_conversions=True),
    "pictures": Group(  # one picture of one thing: the devkit's render_* and their drawing
        ("nuparquet/rendering/pictures/*.py", "!nuparquet/rendering/pictures/nuimages.py",
         "nuparquet/rendering/map_canvas.py"),
        ("tests/parity/test_single_renders_devkit.py", "tests/rendering/test_single_cli.py",
         "tests/rendering/test_topview.py", "tests/rendering/test_charts.py",
         # charts.write_plots in the test's process: the CAN bus charts' file names, the lidarseg chart
         "tests/cli/test_analytics.py::test_stats_plots_writes_four_png_charts_and_two_from_the_can_bus",
         "tests/conversion/test_points.py::test_stats_gains_lidarseg_sections_and_a_chart_when_labels_were_converted",
         # trajectories.py: the predicted trajectories over the map, tested beside the prediction evaluation
         "tests/evaluation/test_prediction_devkit.py::test_predicted_trajectories_are_drawn_over_the_map_by_rank",
         "tests/evaluation/test_prediction_devkit.py::test_the_eval_folder_holds_the_worst_agents_trajectories"),
        keyword="not extract", cache_conversions=True),
    "index": Group(
        ("nuparquet/index/**/*.py",),
        ("tests/index/",),
        keyword="not extract", cache_conversions=True),
    "devkit": Group(
        ("nuparquet/devkit/**/*.py", "!nuparquet/devkit/map_expansion/*.py",
         "!nuparquet/devkit/prediction/input_representation/*.py"),
        ("tests/devkit/", "tests/parity/test_devkit_tables.py", "tests/parity/test_devkit_boxes.py",
         "tests/parity/test_devkit_utils.py", "tests/parity/test_devkit_printers.py",
         "tests/parity/test_devkit_clients.py", "tests/rendering/test_colorings.py",
         "tests/parity/test_predict_helper_devkit.py", "tests/parity/test_devkit_can_bus.py",
         "tests/parity/test_devkit_signatures.py"),
        keyword="not extract", cache_conversions=True),
    "devkit_map": Group(  # the devkit's map expansion face, and the map files' records it and export-json rebuild
        ("nuparquet/devkit/map_expansion/*.py", "nuparquet/sources/map_records.py"),
        ("tests/parity/test_devkit_map_api.py", "tests/parity/test_devkit_map_renders.py",
         "tests/parity/test_devkit_arcline_path_utils.py", "tests/parity/test_devkit_map_edges.py",
         "tests/map/test_map_datasets.py::test_export_json_writes_every_map_file_back_exactly",
         "tests/parity/test_devkit_signatures.py"),
        keyword="not extract", cache_conversions=True),
    "rasters": Group(  # the prediction models' input rasters (issue 37)
        ("nuparquet/devkit/prediction/input_representation/*.py",),
        ("tests/parity/test_input_representation_devkit.py", "tests/parity/test_devkit_signatures.py"),
        cache_conversions=True),
    "evaluation": Group(
        ("nuparquet/evaluation/*.py",),
        ("tests/evaluation/",),
        keyword="not extract", cache_conversions=True),
    "mcap": Group(
        ("nuparquet/mcap/*.py",),
        # the many-scene export's one serial-engine test (the rest of test_mcap_scale_out starts Ray)
        ("tests/mcap/test_export.py", "tests/parity/test_mcap_devkit.py",
         "tests/mcap/test_mcap_scale_out.py::test_missing_files_are_counted_in_the_summary_and_warned"),
        keyword="not extract", cache_conversions=True),
    "site": Group(
        ("nuparquet/site/*.py",),
        ("tests/site/test_report.py",),
        keyword="not extract", cache_conversions=True),
    "cli": Group(
        ("nuparquet/cli/*.py",),
        ("tests/cli/", "tests/rendering/test_single_cli.py", "tests/conversion/test_convert.py",
         # the commands whose CLI tests live beside their library's: eval's printout, one scene's export, the report
         "tests/evaluation/test_config_and_cli.py::test_the_printout_is_the_devkits_main_for_the_same_summary",
         "tests/mcap/test_export.py::test_cli_writes_the_file_and_names_bad_input",
         "tests/site/test_report.py::test_scenes_subset_and_no_videos"),
        keyword="not extract"),
    # --- this stage (issues 36-41) ---------------------------------------------------------------------------------
    "embedded": Group(  # sensor files inside the dataset (`convert --embed`): written, then read back by token
        ("nuparquet/sensors/embedded.py", "nuparquet/conversion/builders/sensor_files.py"),
        ("tests/dataset/test_embedded_sensors.py", "tests/conversion/test_registry.py",
         "tests/conversion/test_trimmed_extracts.py::test_sensor_points_leave_out_the_frames_of_no_scene_and_count_them"),
        keyword="not extract"),
    "sensors": Group(  # the one sensor reader: converted points, embedded files or files, local or remote
        ("nuparquet/sensors/*.py", "!nuparquet/sensors/embedded.py"),
        ("tests/dataset/test_object_store.py", "tests/dataset/test_sensor_reader.py", "tests/parity/test_sweeps_devkit.py",
         "tests/dataset/test_embedded_sensors.py",
         "tests/rendering/test_lidar_colors.py",
         "tests/mcap/test_export.py::test_an_unreadable_point_file_stops_the_export_with_the_reason",
         "tests/conversion/test_truckscenes.py::test_the_sensor_reader_reads_a_pcd_lidar_file_as_lidar_points_names_its_fields"),
        keyword="not extract"),
    "nuimages": Group(
        ("nuparquet/nuimages/*.py", "nuparquet/sources/nuimages.py", "nuparquet/conversion/builders/nuimages.py",
         "nuparquet/rendering/pictures/nuimages.py"),
        ("tests/parity/test_nuimages_devkit.py", "tests/conversion/test_nuimages_convert.py", "tests/test_rle.py"),
        keyword="not extract"),
    "truckscenes": Group(  # MAN TruckScenes: its reader and checks, and its generator (issue 40)
        ("nuparquet/sources/truckscenes.py", "nuparquet/synth/truckscenes.py", "nuparquet/conversion/builders/ego_motion.py"),
        ("tests/conversion/test_truckscenes.py",),
        keyword="not extract"),
    "tracking": Group(  # the tracking benchmark: motmetrics' accumulator replayed, the devkit's metrics
        ("nuparquet/evaluation/tracking/*.py",),
        ("tests/evaluation/test_tracking_devkit.py", "tests/evaluation/test_tracking_matching.py",
         "tests/evaluation/test_tracking_submission.py"),
        keyword="not extract", cache_conversions=True),
    "segmentation": Group(  # the lidarseg benchmark: the devkit's class mapper and confusion-matrix arithmetic
        ("nuparquet/evaluation/segmentation/*.py",),
        ("tests/evaluation/test_lidarseg_devkit.py", "tests/evaluation/test_lidarseg_slices.py"),
        keyword="not extract", cache_conversions=True),
    "panoptic": Group(  # the panoptic benchmarks: the devkit's PanopticEval and PanopticTrackingEval arithmetic
        ("nuparquet/evaluation/panoptic/*.py",),
        ("tests/evaluation/test_panoptic_devkit.py", "tests/evaluation/test_panoptic_slices.py"),
        keyword="not extract", cache_conversions=True),
    "prediction": Group(  # the prediction benchmark: the devkit's futures, ranking, min-k and off-road test
        ("nuparquet/evaluation/prediction/*.py", "nuparquet/frames/annotation_chains.py"),
        ("tests/evaluation/test_prediction_devkit.py", "tests/parity/test_predict_helper_devkit.py"),
        keyword="not extract", cache_conversions=True),
    "training": Group(  # samples for training: the index's arrays read as mmdetection3d's loading pipeline
        ("nuparquet/training/*.py",),
        ("tests/training/",),
        keyword="not extract", cache_conversions=True),
    "synth": Group(  # the generator makes every fixture: its own mutants must make theirs
        ("nuparquet/synth/*.py", "!nuparquet/synth/truckscenes.py"),
        ("tests/synth/", "tests/parity/test_synth_devkit.py"),
        keyword="not extract", cache_data=False),
}


def nothing_to_mutate(path: Path) -> bool:
    """The one exemption from the groups: a package's `__init__.py` that defines no function and no class (only a
    docstring, imports and names). mutmut mutates code inside functions and methods only, so such a file has no
    mutant to give."""
    if path.name != "__init__.py":
        return False
    tree = ast.parse(path.read_text())
    return not any(isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) for node in tree.body)


def package_modules() -> list[str]:
    """Every module of nuparquet/, as a path relative to the repository."""
    return sorted(str(p.relative_to(REPO)) for p in (REPO / "nuparquet").rglob("*.py"))


def group_modules(group: str) -> list[str]:
    """The modules a group mutates: its patterns resolved against the tree, less `nothing_to_mutate`."""
    chosen: set[str] = set()
    for pattern in GROUPS[group].modules:
        matched = {str(p.relative_to(REPO)) for p in REPO.glob(pattern.lstrip("!")) if p.suffix == ".py"}
        chosen = chosen - matched if pattern.startswith("!") else chosen | matched
    return sorted(m for m in chosen if not nothing_to_mutate(REPO / m))


DEFAULT_BUDGET_S = 900
TIMEOUT_MULTIPLIER = 4.0


def stage(group: str, keep_results: bool = False, where: Path | None = None) -> Path:
    """A fresh copy of what the group's tests need, with the group's mutmut configuration. With `keep_results`
    the code and tests are refreshed but mutmut's results (`mutants/`) stay: mutmut regenerates the mutants of
    changed modules, and a run of named mutants updates only theirs."""
    where = where or STAGING / group
    if where.exists() and not keep_results:
        shutil.rmtree(where)
    copy_tree(where)
    shutil.rmtree(where / "conversions", ignore_errors=True)  # made by this staging's unmutated first test run
    pyproject = (REPO / "pyproject.toml").read_text()
    pyproject += (
        "\n[tool.mutmut]\n"
        f"source_paths = {json.dumps(['nuparquet'])}\n"
        f"only_mutate = {json.dumps(group_modules(group))}\n"
        f"do_not_mutate = {json.dumps(list(GROUPS[group].not_mutated))}\n"
        f"also_copy = {json.dumps(['schemas', 'docs'])}\n"
        f"pytest_add_cli_args_test_selection = {json.dumps(GROUPS[group].pytest_args())}\n"
        f"pytest_add_cli_args = {json.dumps(['-p', 'no:cacheprovider', '-p', 'no:xdist', '-q'])}\n"
        # Fixtures (conversions, devkit loads) are rebuilt in every mutant's process but counted in one test's
        # time only: a constant keeps slow set-ups from passing for endless loops. The wall-clock limit is
        # (tests' time + constant) x multiplier: 4 gives a hung mutant two minutes, not mutmut's default 7.5.
        "timeout_constant = 30.0\n"
        f"timeout_multiplier = {TIMEOUT_MULTIPLIER}\n"
        'process_isolation = "forkserver"\n'
    )
    (where / "pyproject.toml").write_text(pyproject)
    return where


def copy_tree(where: Path) -> None:
    """The package, the tests, the schemas and the docs (tests compare generated docs with the committed ones),
    copied into `where` (replacing what was there)."""
    where.mkdir(parents=True, exist_ok=True)
    for name in ("nuparquet", "tests", "schemas", "docs"):
        shutil.rmtree(where / name, ignore_errors=True)
        shutil.copytree(REPO / name, where / name, ignore=shutil.ignore_patterns("__pycache__"))


def group_env(group: str, where: Path) -> dict:
    """The environment of a group's test runs in the staged copy `where`: no PYTHONPATH of a worktree; the caches
    of generated dataroots (shared by the groups) and of conversions (the group's own, made afresh with each
    staging: `where/conversions`)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(MPLBACKEND="Agg")
    if GROUPS[group].serial_engine:
        env["NUPARQUET_TEST_SERIAL_ENGINE"] = "1"
    if GROUPS[group].cache_data:
        env["NUPARQUET_TEST_CACHE"] = str(STAGING / "cache")
        if GROUPS[group].cache_conversions:
            env["NUPARQUET_TEST_CACHE_CONVERSIONS"] = str(where / "conversions")
    return env


def all_mutants(where: Path, env: dict) -> list[str]:
    """Every mutant of a staged group, generated if need be (a run of a name matching no mutant generates them
    and tests none)."""
    listed = subprocess.run(MUTMUT + ["results", "--all", "true"], cwd=where, env=env, capture_output=True, text=True)
    if not listed.stdout.strip():
        subprocess.run(MUTMUT + ["run", "nuparquet.no_such_module.x_none__mutmut_0"], cwd=where, env=env,
                       capture_output=True, check=False)
        listed = subprocess.run(MUTMUT + ["results", "--all", "true"], cwd=where, env=env, capture_output=True,
                                text=True)
    return [line.split(":")[0].strip() for line in listed.stdout.splitlines() if "__mutmut_" in line]


def recheck_stage(group: str, env: dict) -> Path:
    """`.mutation/<group>-recheck/`: the group with the current code and tests, its mutants generated and mutmut's
    stats collected, then every function mapped to every selected test.

    mutmut maps a function to the tests during which it ran, and a module-scoped fixture runs in the first test that
    uses it: a builder called while a fixture converts a dataset is mapped to that one test, and its mutants are
    run against it alone (`path_lengths` mutants survived while `test_scenes_and_instances_from_the_json` checks
    every track length). A re-check runs each named mutant against the whole selection instead (pytest -x stops
    at the first failure)."""
    where = stage(group, where=STAGING / f"{group}-recheck")
    names = all_mutants(where, env)  # generates the mutants and collects the stats
    stats_file = where / "mutants" / "mutmut-stats.json"
    stats = json.loads(stats_file.read_text())
    every_test = sorted(stats["duration_by_test"])
    functions = set(stats["tests_by_mangled_function_name"]) | {name.partition("__mutmut_")[0] for name in names}
    stats["tests_by_mangled_function_name"] = {name: every_test for name in sorted(functions)}
    stats_file.write_text(json.dumps(stats))
    return where


_FUNCTIONS: dict[Path, tuple[list[str], dict[str, tuple[int, int]]]] = {}


def mutant_change(where: Path, name: str) -> tuple[list[str], list[str]]:
    """The lines a mutant changes (old, new), read from mutmut's mutated module in `where/mutants/`: the mutant's
    function against the `__mutmut_orig` one. (`mutmut show` parses the whole module once per mutant: minutes for a
    module of thousands of mutants.)"""
    module, function = name.rsplit(".", 1)
    path = where / "mutants" / (module.replace(".", "/") + ".py")
    if not path.is_file():  # a package's own module: `nuparquet.engine` is nuparquet/engine/__init__.py
        path = path.with_suffix("") / "__init__.py"
    if path not in _FUNCTIONS:
        source = path.read_text()
        spans = {node.name: (node.lineno, node.end_lineno) for node in ast.walk(ast.parse(source))
                 if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))}
        _FUNCTIONS[path] = (source.splitlines(), spans)
    lines, spans = _FUNCTIONS[path]
    original = function.rsplit("__mutmut_", 1)[0] + "__mutmut_orig"
    if function not in spans or original not in spans:
        return [], []
    body = {n: lines[spans[n][0]:spans[n][1]] for n in (original, function)}  # without the def line (its name)
    old, new = [], []
    for line in difflib.unified_diff(body[original], body[function], lineterm="", n=0):
        if line[:1] in "+-" and not line.startswith(("+++", "---")):
            (old if line[0] == "-" else new).append(line[1:].strip())
    return old, new


def run_group(group: str, budget_s: float, max_children: int, mutants: list[str] | None = None,
              sample: int | None = None, seed: int = 0, recheck: bool = False) -> dict:
    env = group_env(group, STAGING / (f"{group}-recheck" if recheck else group))
    # a sampled run of a group whose staging holds the same sample goes on where it stopped (its results kept)
    resume = bool(sample) and (STAGING / group / "sample.txt").is_file() and not recheck
    where = recheck_stage(group, env) if recheck else stage(group, keep_results=bool(mutants) or resume)
    if sample:  # a uniform random sample of the group's mutants, the same for the same seed and code
        names = sorted(all_mutants(where, env))
        mutants = sorted(random.Random(seed).sample(names, min(sample, len(names))))
        if resume and (where / "sample.txt").read_text().split() != mutants:
            raise SystemExit(f"{group}: the staged sample is not the sample of --sample {sample} --seed {seed} of "
                             "this code; remove .mutation/" + group + " to start again")
        (where / "sample.txt").write_text("\n".join(mutants) + "\n")
    started = time.monotonic()
    log = open(where / "mutmut.log", "w")  # noqa: SIM115 - closed below; mutmut's progress is one long line
    process = subprocess.Popen(MUTMUT + ["run", "--max-children", str(max_children), *(mutants or [])], cwd=where, env=env,
                               stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        process.wait(timeout=budget_s)
        finished = True
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGTERM)  # our own process group only
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
        finished = False
    elapsed = time.monotonic() - started
    log.close()
    subprocess.run(MUTMUT + ["export-cicd-stats"], cwd=where, env=env, check=False, capture_output=True)
    stats_file = where / "mutants" / "mutmut-cicd-stats.json"
    stats = json.loads(stats_file.read_text()) if stats_file.exists() else {}
    survivors = subprocess.run(MUTMUT + ["results"], cwd=where, env=env, capture_output=True, text=True).stdout
    (where / "survivors.txt").write_text(survivors)
    with open(where / "survivors.diff", "w") as diffs:  # each survivor's change, for MUTATION.md
        for line in survivors.splitlines():
            name = line.split(":")[0].strip()
            if line.strip().endswith("survived"):
                old, new = mutant_change(where, name)
                diffs.write(f"## {name}\n" + "\n".join([*(f"-{o}" for o in old), *(f"+{n}" for n in new)]) + "\n")
    result = {"group": group, "finished": finished, "elapsed_s": round(elapsed), "stats": stats,
              "sample": {"size": len(mutants), "seed": seed} if sample else None,
              "again": [] if sample else (mutants or []), "survivors": [line.strip() for line in survivors.splitlines()
                            if line.strip() and not line.strip().endswith("not checked")]}
    (where / "result.json").write_text(json.dumps(result, indent=1))
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("groups", nargs="*", metavar="GROUP",
                        help=f"groups to run (default all): {', '.join(GROUPS)}")
    parser.add_argument("--budget-s", type=float, default=DEFAULT_BUDGET_S, help="time budget per group, seconds")
    parser.add_argument("--max-children", type=int, default=2, help="mutants tested in parallel (default 2)")
    parser.add_argument("--again", nargs="+", metavar="NAME",
                        help="with one GROUP: re-run only these mutants (mutmut names or globs, e.g. "
                             "'nuparquet.geometry.x_slerp_amount*') against the current code and tests, keeping the "
                             "group's other results")
    parser.add_argument("--recheck", nargs="+", metavar="NAME",
                        help="with one GROUP: re-run these mutants (names or globs) against every selected test, in "
                             "a separate staging copy (.mutation/GROUP-recheck), leaving the group's results as they "
                             "are; mutation/report.py then takes the re-checked verdicts")
    parser.add_argument("--sample", type=int, metavar="N",
                        help="test a uniform random sample of N mutants of each group (a 2-core machine cannot run "
                             "the reader's or the builders' ~1,100 mutants in a session); the score is then an "
                             "estimate over the sample")
    parser.add_argument("--seed", type=int, default=0, help="seed of --sample (default 0)")
    parser.add_argument("--hand", action="store_true",
                        help="run the hand-made mutants of mutation/hand_mutants.toml (of GROUPs, default all) "
                             "instead of mutmut's: mutation/hand.py")
    args = parser.parse_args(argv)
    if args.hand:
        import hand

        return hand.main(args.groups)
    if (args.again or args.recheck) and len(args.groups) != 1:
        parser.error("--again and --recheck need exactly one GROUP")
    unknown = [g for g in args.groups if g not in GROUPS]
    if unknown:
        parser.error(f"unknown group(s) {', '.join(unknown)}; valid: {', '.join(GROUPS)}")
    results = []
    for group in args.groups or list(GROUPS):
        result = run_group(group, args.budget_s, args.max_children, args.recheck or args.again, args.sample, args.seed,
                           recheck=bool(args.recheck))
        results.append(result)
        print(json.dumps(result, indent=1), flush=True)
    # the last result of every group run so far, whichever invocation ran it
    summary = [json.loads((STAGING / g / "result.json").read_text()) for g in GROUPS
               if (STAGING / g / "result.json").is_file()]
    (STAGING / "summary.json").write_text(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
