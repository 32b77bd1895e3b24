"""Reports read one variant of finished runs: an ablation (a run with overrides beyond the experiment's own sweep
keys) never replaces a default run, unfinished runs are never read, every section names the sweeps it read, and
the prose states settings from the runs' logged params."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pandas as pd
import pytest
from mlflow.tracking import MlflowClient
from omegaconf import OmegaConf

from hrc_lab.config import LoggerConfig
from hrc_lab.report.build import build_report
from hrc_lab.report.callbacks import SweepSummary
from hrc_lab.report.headline import within
from hrc_lab.report.plan import Pick, Plan, Row, Study
from hrc_lab.report.runs import fetch_runs, setting, variants_of
from hrc_lab.report.sections import SECTIONS, load_sections
from hrc_lab.run_naming import variant_of
from hrc_lab.tracking import RunTracker

ROOT = Path(__file__).resolve().parents[1]

EXPERIMENT = "ch4/table_4_1"
TITLE = "## Table 4.1: reasoning success rates"
LEGACY_SWEEP, DEFAULT_SWEEP, ABLATION_SWEEP, UNFINISHED_SWEEP = (
    "2026-11-20_08-00-00",
    "2026-11-21_09-00-00",
    "2026-11-22_10-00-00",
    "2026-11-23_11-00-00",
)
ABLATION = "protocol.min_demos=60"
ABLATION_VARIANT = variant_of([ABLATION], [])[0]  # the variant tag hrc-lab gives a job with that override


def log_run(logger: LoggerConfig, *, cell: str, sweep: str, sr: float, variant: str | None = "default",
            extra: str = "", min_demos: int = 200, status: str = "FINISHED", seed: int = 0,
            config: dict | None = None, metrics: dict | None = None) -> str:
    """One run as ``hrc-lab experiment=ch4/table_4_1`` logs it: tags, resolved config as params, final metrics.
    ``variant=None`` leaves out the variant tags (runs logged before they existed); ``config`` and ``metrics`` add
    config keys and metrics."""
    base = f"env=package_to_order_{cell} reasoning=ours seed={seed}"
    tags = {"chapter": "ch4", "table": "table_4_1", "experiment": EXPERIMENT, "method": "ours", "cell": cell,
            "scenario": cell, "seed": str(seed), "sweep": sweep}
    if variant is not None:
        tags |= {"variant": variant, "overrides": f"{base} {extra}".strip(), "variant_overrides": extra}
    tracker = RunTracker(logger, EXPERIMENT, f"{EXPERIMENT}-ours-{cell}-seed{seed}", tags)
    tracker.__enter__()
    cfg = OmegaConf.create({"name": EXPERIMENT, "seed": seed,
                            "protocol": {"name": "ch4_table_4_1", "min_demos": min_demos, "n_folds": 5},
                            **(config or {})})
    tracker.log_config(cfg)
    tracker.log_metrics({"sr": sr, "latency_ms_batch1": 1.25, "latency_ms_batched": 0.05, **(metrics or {})})
    if status == "FINISHED":
        tracker.__exit__(None, None, None)
    elif status != "RUNNING":
        tracker.client.set_terminated(tracker.run_id, status)
    time.sleep(0.02)  # start times in ms: each run is strictly newer than the one before
    return tracker.run_id


def section_text(markdown: str, heading: str) -> str:
    """The body of the section whose heading line is exactly ``heading`` (up to the next section)."""
    lines = markdown.splitlines()
    start = lines.index(heading)
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
    return "\n".join(lines[start:end])


def row_of(section: str, method: str = "Ours") -> str:
    return next(line for line in section.splitlines() if line.startswith(f"| {method} "))


@pytest.fixture
def store(tmp_path):
    """A sqlite MLflow store with, oldest first: a 3of5 run logged before the variant tags, the default 4of5 run,
    a newer ablation of it, and newer RUNNING and KILLED default runs of the same job."""
    logger = LoggerConfig(tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}",
                          artifact_root=str(tmp_path / "mlartifacts"))
    log_run(logger, cell="3of5", sweep=LEGACY_SWEEP, sr=0.7, variant=None)
    log_run(logger, cell="4of5", sweep=DEFAULT_SWEEP, sr=0.9)
    log_run(logger, cell="4of5", sweep=ABLATION_SWEEP, sr=0.1, variant=ABLATION_VARIANT, extra=ABLATION, min_demos=60)
    log_run(logger, cell="4of5", sweep=UNFINISHED_SWEEP, sr=0.55, status="RUNNING")
    log_run(logger, cell="4of5", sweep=UNFINISHED_SWEEP, sr=0.35, status="KILLED")
    return logger


def test_fetch_runs_selects_one_variant_and_only_finished_runs(store):
    uri = store.tracking_uri
    statuses = sorted(r.info.status for r in MlflowClient(uri).search_runs(
        [MlflowClient(uri).get_experiment_by_name(EXPERIMENT).experiment_id]))
    assert statuses == ["FINISHED", "FINISHED", "FINISHED", "KILLED", "RUNNING"]

    default = fetch_runs(uri, EXPERIMENT).set_index("cell")
    assert sorted(default.index) == ["3of5", "4of5"]
    assert default.loc["4of5", "sr"] == pytest.approx(0.9)  # not the newer ablation, RUNNING or KILLED run
    assert default.loc["3of5", "sr"] == pytest.approx(0.7)  # no variant tag: a default run
    assert set(default.variant) == {"default"} and set(default.status) == {"FINISHED"}
    assert default.loc["4of5", "sweep"] == DEFAULT_SWEEP and default.loc["3of5", "sweep"] == LEGACY_SWEEP
    assert default.loc["4of5", "param.protocol.min_demos"] == "200"

    ablation = fetch_runs(uri, EXPERIMENT, variant=ABLATION_VARIANT)
    assert ablation.sr.tolist() == [pytest.approx(0.1)] and ablation.sweep.tolist() == [ABLATION_SWEEP]
    assert len(fetch_runs(uri, EXPERIMENT, variant=None)) == 3
    assert fetch_runs(uri, EXPERIMENT, sweep=UNFINISHED_SWEEP, variant=None).empty
    assert fetch_runs(uri, EXPERIMENT, sweep=ABLATION_SWEEP).empty  # that sweep holds no default run
    assert variants_of(fetch_runs(uri, EXPERIMENT, variant=None)) == {"default": "", ABLATION_VARIANT: ABLATION}
    assert variants_of(fetch_runs(uri, EXPERIMENT, sweep=DEFAULT_SWEEP, variant=None)) == {"default": ""}


def plan_with(*studies: Study, rows: tuple = ()) -> Plan:
    """A one-report plan over this file's Table 4.1 runs: the studies given, in order."""
    return Plan("ch4_reasoning", "Ch.4 reasoning", "Our scenes.", studies=studies, rows=rows)


ABLATION_STUDY = Study(EXPERIMENT, (ABLATION,), key="few_demos", title="Table 4.1 with 60 task episodes",
                       question="Does the module need the thesis' 200 episodes?")


def test_a_report_shows_its_plan_s_studies_and_no_other_runs(store, tmp_path):
    """The default study reads the default runs; an ablation study its own variant's runs only, under its own
    title with its question; runs of a variant no study names (the store may hold any) are in no section."""
    markdown = build_report(plan_with(Study(EXPERIMENT), ABLATION_STUDY), store.tracking_uri,
                            tmp_path / "reports").read_text()
    print(markdown)
    default = section_text(markdown, TITLE)
    assert f"Runs: sweeps {LEGACY_SWEEP} (1 run), {DEFAULT_SWEEP} (1 run)" in default
    assert "0.10" not in default and "0.55" not in default and "0.35" not in default
    assert default.split("\n")[2] == "Reproduce: `hrc-lab experiment=ch4/table_4_1 hydra/launcher=joblib`"

    ablation = section_text(markdown, "## Table 4.1 with 60 task episodes")
    assert f"Runs: sweep {ABLATION_SWEEP} (1 run); variant {ABLATION_VARIANT}" in ablation
    assert ablation.split("\n")[2] == (f"Reproduce: `hrc-lab experiment=ch4/table_4_1 {ABLATION} "
                                       "hydra/launcher=joblib`")
    assert "**Question.** Does the module need the thesis' 200 episodes?" in ablation
    assert '<a id="few_demos"></a>' in markdown and "0.90" not in ablation
    assert markdown.index(TITLE + "\n") < markdown.index("## Table 4.1 with 60 task episodes")
    assert (tmp_path / "reports" / "ch4_reasoning" / "few_demos.csv").is_file()

    without = build_report(plan_with(Study(EXPERIMENT)), store.tracking_uri, tmp_path / "reports").read_text()
    assert "0.10" not in without and "60 task episodes" not in without  # in the store, in no study
    assert not (tmp_path / "reports" / "ch4_reasoning" / "few_demos.csv").exists()  # a gone study's files go


def test_a_study_without_runs_says_so_and_the_header_names_it(store, tmp_path):
    other = Study(EXPERIMENT, ("protocol.min_demos=5",), key="five", title="Table 4.1 with 5 task episodes")
    markdown = build_report(plan_with(Study(EXPERIMENT), other), store.tracking_uri, tmp_path / "r").read_text()
    assert ("## Table 4.1 with 5 task episodes\n\nNot run yet: `hrc-lab experiment=ch4/table_4_1 "
            "protocol.min_demos=5 hydra/launcher=joblib`") in markdown
    assert "(2 studies; not run yet: five)" in markdown


def test_the_header_names_the_store_commit_and_machine_of_the_runs(store, tmp_path):
    from hrc_lab.processes import code_identity

    markdown = build_report(plan_with(Study(EXPERIMENT)), store.tracking_uri, tmp_path / "r").read_text()
    head = "\n".join(markdown.splitlines()[:4])
    assert f"from the store `{store.tracking_uri}`" in head
    assert f"at commit `{code_identity()['commit'][:10]}`" in head and "CPU kernels" in head
    assert "Runs: 2 finished" in head  # the default study's two runs; the ablation is in no study


def test_the_opening_table_puts_the_thesis_row_beside_ours_and_the_scoreboard_gathers_it(store, tmp_path):
    """A plan row reads the thesis' values from thesis_results.yaml and ours from the section's results; the
    scoreboard (reports/README.md) is rebuilt with every report, from each report's thesis rows."""
    rows = (Row("Table 4.1", "Ours", "ch4.table_4_1.ours", Pick("table_4_1", "ours"), columns=("3of5", "4of5"),
                why="our scenes"),)
    out = tmp_path / "reports"
    markdown = build_report(plan_with(Study(EXPERIMENT), rows=rows), store.tracking_uri, out).read_text()
    opening = markdown.split("## The thesis' results beside ours")[1].split("\n## ")[0]
    assert "| Ours | thesis | 1.00 ± 0.00 | 1.00 ± 0.00 |  |" in opening
    assert "| | [as written (1 seed)](#table_4_1) | 0.70 | 0.90 | our scenes |" in opening.replace("|  |", "| |")
    board = (out / "README.md").read_text()
    assert "| Table 4.1, Ours (3of5 / 4of5) | 1.00 / 1.00 | 0.70 / 0.90 |  | no | [ch4_reasoning](ch4_reasoning.md) |" \
        in board


def test_within_the_spread_reads_the_larger_spread_and_the_direction():
    assert within(0.91, 0.0, 0.92, 0.012, higher=True)  # 0.01 short, inside the thesis' spread 0.012
    assert not within(0.90, 0.0, 0.92, 0.012, higher=True)  # 0.02 short
    assert within(0.89, 0.04, 0.92, 0.012, higher=True)  # our spread over seeds covers it
    assert within(0.99, 0.0, 0.92, 0.012, higher=True)  # above
    assert within(40.0, 0.0, 41.0, 2.0, higher=False) and not within(45.0, 1.0, 41.0, 2.0, higher=False)


def test_sweep_summary_reads_its_own_sweep_and_variant(store, tmp_path):
    sweep_dir = tmp_path / "multirun" / ABLATION_SWEEP
    config = OmegaConf.create({
        "name": EXPERIMENT, "table": "table_4_1", "chapter": "ch4",
        "logger": {"tracking_uri": store.tracking_uri, "artifact_root": store.artifact_root},
        "hydra": {"sweep": {"dir": str(sweep_dir)}},
    })
    SweepSummary().on_multirun_end(config)
    summary = (sweep_dir / "summary.md").read_text()
    assert summary.startswith(f"{TITLE}\n")
    assert f"Runs: sweep {ABLATION_SWEEP} (1 run); variant {ABLATION_VARIANT}" in summary
    assert "0.10 (1.00)" in row_of(summary) and "0.90" not in summary
    client = MlflowClient(store.tracking_uri)
    experiment = client.get_experiment_by_name(EXPERIMENT).experiment_id
    (summary_run,) = client.search_runs([experiment], "tags.kind = 'summary'")
    assert summary_run.data.tags["variant"] == ABLATION_VARIANT
    assert len(fetch_runs(store.tracking_uri, EXPERIMENT, variant=None)) == 3  # summary runs are not jobs


def test_a_failing_sweep_summary_makes_the_sweep_exit_non_zero(store, tmp_path, monkeypatch, capsys):
    """Hydra only warns about an exception in a callback; the summary turns it into exit 1 with the report's command."""
    import hrc_lab.report.build

    def broken(*args, **kwargs):
        raise KeyError("a column the section expects")

    monkeypatch.setattr(hrc_lab.report.build, "sections_from", broken)
    config = OmegaConf.create({
        "name": EXPERIMENT, "table": "table_4_1", "chapter": "ch4",
        "logger": {"tracking_uri": store.tracking_uri, "artifact_root": store.artifact_root},
        "hydra": {"sweep": {"dir": str(tmp_path / "multirun" / DEFAULT_SWEEP)}},
    })
    with pytest.raises(SystemExit) as exit_info:
        SweepSummary().on_multirun_end(config)
    assert exit_info.value.code == 1
    err = capsys.readouterr().err
    assert "a column the section expects" in err and "its report: `hrc-lab-report ch4_reasoning`" in err


def test_prose_reads_settings_from_params_or_says_not_logged():
    load_sections()
    runs = pd.DataFrame({"method": ["gnn_att", "gnn_att"], "seed": [0, 1], "cell": ["clutter"] * 2,
                         "param.grasp.detector.context_scale": ["1.8", "1.8"]})
    assert "enlarged 1.8× (`grasp.detector.context_scale`" in SECTIONS["table_6_1"](runs).markdown
    off = SECTIONS["table_6_1"](runs.assign(**{"param.grasp.detector.context_scale": "0.0"})).markdown
    assert "no enlarged-box feature" in off and "1.8" not in off
    old = SECTIONS["table_6_1"](runs.drop(columns="param.grasp.detector.context_scale")).markdown
    assert "not logged" in old and "1.8" not in old
    assert setting(runs, "protocol.n_folds") == "not logged"


def test_table_6_1_section_decomposes_the_object_accuracy():
    load_sections()
    seeds = [0, 1]
    runs = pd.DataFrame({
        "method": ["gnn_att"] * 2, "seed": seeds, "cell": ["clutter"] * 2, "run_id": ["r0", "r1"],
        "train_grasp_acc": [0.99, 1.0], "train_part_grasp_acc": [0.95, 0.96], "train_detected": [0.97, 0.97],
        **{f"{stem}_{k}": [0.8, 0.9] for stem in ("oa", "fit_acc", "detected") for k in (1, 2, 3)},
        "oa_type_a": [0.6, 0.7], "oa_type_b": [0.9, 0.9], "oa_type_c": [1.0, 1.0],
        "geometry_blockers_within_filter": [0.97] * 2, "geometry_blocker_distance_median": [0.08] * 2,
        "geometry_blocker_distance_max": [0.2] * 2, "geometry_pairs_within_filter": [0.3] * 2,
        "geometry_pair_distance_median": [0.25] * 2, "geometry_neighbours_within_filter": [1.5] * 2,
        "geometry_blocker_weight_ratio": [2.5] * 2,
    })
    section = SECTIONS["table_6_1"](runs)
    assert "| GNN_Att (ours) | 0.995 ± 0.005 (1.000)" in section.markdown  # Train_Acc: the solver's fit
    assert "test: OA of part a" in section.markdown and "0.650 ± 0.050" in section.markdown
    assert "OA about 0.81 (Sec. 6.4.1)" in section.markdown
    assert "97% lie within 0.16" in section.markdown and "2.50× the uniform weight" in section.markdown
    assert section.artifacts == {"geometry.png": ("r0", "figures/geometry.png")}
    older = SECTIONS["table_6_1"](runs.drop(columns=["train_detected", "geometry_blockers_within_filter"]))
    assert "Where the object accuracy is lost" not in older.markdown and "lie within" not in older.markdown


def test_table_6_1_default_section_plots_the_oa_over_the_training_set_size(monkeypatch, tmp_path):
    """The default section reads the runs whose only override is ``protocol.train_images`` beside its own, per
    method run at two sizes or more; a run with another override too stays out."""
    from hrc_lab.report import ch6_grasp

    load_sections()

    def run(method, seed, images, variant="default", overrides=""):
        return {"method": method, "seed": seed, "cell": "clutter", "run_id": f"{method}{seed}{images}{variant}",
                "variant": variant, "variant_overrides": overrides, "experiment": "ch6/table_6_1",
                "param.logger.tracking_uri": f"sqlite:///{tmp_path}/x.db", "param.protocol.train_images": str(images),
                **{f"oa_{k}": images / 5000 + k / 100 + seed / 50 for k in (1, 2, 3)}, "train_grasp_acc": 1.0}

    every = pd.DataFrame([run("gnn_att", 0, 427), run("gnn_att", 1, 427), run("gcn_att", 0, 427),
                          run("gnn_att", 0, 1708, "v1", "protocol.train_images=1708"),
                          run("gnn_att", 1, 1708, "v1", "protocol.train_images=1708"),
                          run("gcn_att", 0, 1708, "v2", "protocol.train_images=1708 grasp.steps=10")])
    monkeypatch.setattr(ch6_grasp, "fetch_runs", lambda uri, experiment, variant: every)
    monkeypatch.setattr(ch6_grasp, "finished_runs", lambda uri, experiment: every)
    section = SECTIONS["table_6_1"](every[every.variant == "default"])
    assert "training_images.png" in section.figures
    table = section.markdown.split("Over the number of training images")[1]
    assert ("| GNN_Att (ours) | 0.105 ± 0.010 / 0.115 ± 0.010 / 0.125 ± 0.010 | 0.362 ± 0.010 / 0.372 ± 0.010 / "
            "0.382 ± 0.010 |" in re.sub(r" +", " ", table))
    assert "GCN_Att" not in table  # its 1708-image run has another override too
    ablation = SECTIONS["table_6_1"](every[every.variant == "v1"])
    assert "Over the number of training images" not in ablation.markdown


def test_table_6_1_default_section_measures_how_far_other_cpu_kernels_move_a_cell(monkeypatch, tmp_path):
    """Default runs of one method and seed under two ``cpu_kernels`` settings (no tag: before the pinning) are
    paired; a seed run under one setting only stays out, and without a pair the section says nothing."""
    from hrc_lab.report import ch6_grasp

    load_sections()

    def run(seed, kernels, oa):
        return {"method": "gnn_att", "seed": seed, "cell": "clutter", "run_id": f"{seed}{kernels}",
                "variant": "default", "variant_overrides": "", "experiment": "ch6/table_6_1",
                "param.logger.tracking_uri": f"sqlite:///{tmp_path}/x.db", "cpu_kernels": kernels, "cpu": "CPU X",
                "cpu_capability": "AVX2" if kernels else "AVX512",
                **{f"oa_{k}": oa + k / 100 for k in (1, 2, 3)}, "train_grasp_acc": 1.0}

    every = pd.DataFrame([run(0, "PINNED", 0.80), run(1, "PINNED", 0.84),  # newest first
                          run(0, None, 0.78), run(1, None, 0.88), run(2, None, 0.90)])
    monkeypatch.setattr(ch6_grasp, "fetch_runs", lambda uri, experiment, variant: every.iloc[:0])
    monkeypatch.setattr(ch6_grasp, "finished_runs", lambda uri, experiment: every)
    markdown = re.sub(r" +", " ", SECTIONS["table_6_1"](every.iloc[:2]).markdown)
    assert "the 6 cells (seed x request size) moved by 0.030 on average, at most 0.040" in markdown
    assert "widest paths of their CPU, here AVX512), same config and seeds, on CPU X." in markdown
    # means 0.83 / 0.84 per size (std 0.02 / 0.05): 0.01 within the larger std in each of the 3 cells
    assert "Of the 3 cells of the table (a method's mean over seeds at one request size), 0 moved" in markdown
    assert "the means moved by 0.010 on average, at most 0.010." in markdown
    assert f"| GNN_Att (ours) | {ch6_grasp.KERNELS_BEFORE} | 0, 1 | 0.840 ± 0.050 |" in markdown
    assert "| GNN_Att (ours) | PINNED | 0, 1 | 0.830 ± 0.020 |" in markdown
    monkeypatch.setattr(ch6_grasp, "finished_runs", lambda uri, experiment: every.iloc[:2])
    assert "other CPU kernels" not in SECTIONS["table_6_1"](every.iloc[:2]).markdown


def test_table_6_2_section_gives_the_failure_causes_and_answer_lengths(monkeypatch):
    from hrc_lab.report import ch6_grasp

    load_sections()
    runs = pd.DataFrame({"method": ["gnn_att"] * 2, "seed": [0, 1], "cell": ["clutter"] * 2, "run_id": ["r0", "r1"],
                         "acc_3": [0.7, 0.8], "fail_detection_3": [0.1, 0.0], "fail_graspability_3": [0.2, 0.1],
                         "fail_solution_3": [0.0, 0.1], "fail_other_3": [0.0, 0.0]})
    cases = pd.DataFrame({"objects": [3, 3, 3, 3], "correct": [True, True, False, True], "iterations": [1, 1, 2, 1],
                          "help": [False, False, False, True], "rule_requests": [1, 2, 2, 1]})
    monkeypatch.setattr(ch6_grasp, "run_tables", lambda runs, name: cases if name == "table_6_2_single" else None)
    markdown = SECTIONS["table_6_2_single"](runs).markdown
    assert "| graspability    | 0.150 ± 0.050" in markdown
    assert "acted on in the robosuite cell) is in [ch6_robot.md](ch6_robot.md)" in markdown
    assert re.search(r"\|\s+3 \|\s+4 \|\s+1.25 \|\s+0.75 \|\s+0.25 \|\s+1.5 \|\s+0.5 \|", markdown)
    assert "Why answers are wrong" not in SECTIONS["table_6_2_single"](runs.drop(columns="fail_detection_3")).markdown


def test_table_6_2_robot_section_gives_causes_and_times():
    load_sections()
    runs = pd.DataFrame({"method": ["gnn_att"] * 2, "seed": [0, 1], "cell": ["clutter"] * 2, "run_id": ["r0", "r1"],
                         "acc_3": [0.6, 0.8], "fail_slip_3": [0.1, 0.0], "fail_collision_3": [0.3, 0.2],
                         "fail_detection_3": [0.0, 0.0], "render_ms": [30.0, 32.0], "detection_ms": [50.0, 52.0],
                         "reasoning_ms": [6.0, 6.0], "motion_ms": [4000.0, 4200.0],
                         "perception_reasoning_ms": [86.0, 90.0], "param.protocol.cases": ["30"] * 2,
                         "video_scene": [float("nan"), 2.0], "param.protocol.video_objects": ["5"] * 2})
    section = SECTIONS["table_6_2_robot"](runs)
    markdown = section.markdown
    assert "seed 1, scene 2 with 5 parts" in markdown  # the one run that filmed an episode
    assert section.artifacts["robot_episode.mp4"] == ("r1", "videos/robot_episode.mp4")
    assert "| robot grasping (ours, GNN_Att) | 0.700 ± 0.100 (0.91) |" in markdown
    assert re.search(r"\| detection\s+\| 0.000 ± 0.000 \|\n\| slip\s+\| 0.050 ± 0.050 \|\n\| collision", markdown)
    assert "together 88.0 ± 2.0 ms per iteration" in markdown and "30 scenes per part count" in markdown


def test_table_6_3_section_says_whose_data_it_read():
    load_sections()
    runs = pd.DataFrame({"method": ["gnn_att", "gnn_att", "gvmrn_rf"], "seed": [0, 1, 0], "cell": ["clutter"] * 3,
                         "run_id": ["r0", "r1", "r2"], "ia": [0.5, 0.6, 0.3], "ia_3": [0.7, 0.8, 0.4],
                         "oa": [0.8, 0.9, 0.6], "written_by_hrc_lab": [1.0] * 3,
                         "param.protocol.train_images": ["427"] * 3, "param.protocol.test_images": ["50"] * 3})
    markdown = SECTIONS["table_6_3"](runs).markdown
    assert re.search(r"\| GNN_Att \(ours\) \| 0.550 ± 0.050 \|\s+0.62\s+\| 0.750 ± 0.050\s+\| 0.850 ± 0.050", markdown)
    assert "our 427 trainval and 50 test rendered clutter scenes" in markdown and "not comparable" in markdown
    theirs = SECTIONS["table_6_3"](runs.assign(written_by_hrc_lab=0.0, classes=31.0,
                                               **{"param.env.vmrd_root": "/data/VMRD", "param.env.image_size": "320"}))
    assert "the data set at `/data/VMRD`" in theirs.markdown and "not comparable" not in theirs.markdown
    assert "these runs read 31 classes from the data set's annotations" in theirs.markdown
    assert "letterboxed to 320 px (`env.image_size`) square" in theirs.markdown
    assert theirs.title == "Table 6.3: image-based accuracy (a data set in VMRD's layout)"


def markdown_tables(text: str) -> list[tuple[int, str, str]]:
    """(line number, header row, delimiter row) of every pipe table in a markdown text."""
    lines = text.splitlines()
    delimiter = re.compile(r"^\|(\s*:?-+:?\s*\|)+$")
    return [(i, lines[i - 1], line) for i, line in enumerate(lines) if i and delimiter.match(line)
            and lines[i - 1].startswith("|")]


def cells(row: str) -> int:
    return len(re.split(r"(?<!\\)\|", row.strip())) - 2


@pytest.mark.parametrize("report", sorted(p.name for p in (ROOT / "reports").glob("*.md")))
def test_every_committed_report_table_has_as_many_header_cells_as_columns(report):
    """A "|" inside a header cell (e.g. |P_obj − P_goal|) splits it, and GitHub then renders no table at all:
    header and delimiter rows must have the same number of cells (norms are written ‖x‖)."""
    text = (ROOT / "reports" / report).read_text()
    for line, header, delimiter in markdown_tables(text):
        assert cells(header) == cells(delimiter), f"{report}:{line}: {header[:120]}"
