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
from hrc_lab.report.runs import fetch_runs, variants_of
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
    assert within(0.91, 0.0, 3, 0.92, 0.012, higher=True)  # 0.01 short, inside the thesis' spread 0.012
    assert not within(0.90, 0.0, 3, 0.92, 0.012, higher=True)  # 0.02 short
    assert within(0.89, 0.06, 3, 0.92, 0.012, higher=True)  # our mean's standard error 0.035 covers it
    assert not within(0.80, 0.16, 3, 0.92, 0.012, higher=True)  # a wide scatter over 3 seeds does not
    assert within(0.99, 0.0, 3, 0.92, 0.012, higher=True)  # above
    assert within(40.0, 0.0, 3, 41.0, 2.0, higher=False) and not within(45.0, 1.0, 3, 41.0, 2.0, higher=False)


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


def test_plans_md_gives_each_reports_studies_runs_commit_and_wall_time(tmp_path):
    from hrc_lab.report.times import PLAN_FILE, write_plan_times

    for topic, rows in {"ch9_a": [("one", 6, "abc1234567", 0.5), ("two", 0, "", float("nan"))],
                        "ch9_b": [("three", 3, "abc1234567", 0.25)]}.items():
        (tmp_path / topic).mkdir()
        pd.DataFrame([{"topic": topic, "study": s, "title": s, "runs": n, "commit": c, "hours": h, "cpu": "CPU X"}
                      for s, n, c, h in rows]).to_csv(tmp_path / topic / PLAN_FILE, index=False)
    text = write_plan_times(tmp_path).read_text()
    assert "| ch9_a | 1 of 2 | 6 | abc1234567 | 0.50 |" in text
    assert "| all | 2 of 3 | 9 |  | 0.75 |" in text
    assert "| ch9_a | two | 0 | not run yet |" in text and "| ch9_b | three | 3 | 15 |" in text
    assert "CPU: CPU X." in text


def test_a_run_is_tagged_edited_only_when_its_code_differs_from_the_commit(tmp_path, monkeypatch):
    import subprocess

    from hrc_lab import processes

    for path in ("hrc_lab/a.py", "conf/a.yaml", "reports/a.md"):
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text("x\n")
    git = ["git", "-C", str(tmp_path), "-c", "user.email=t@t", "-c", "user.name=t"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "c"], check=True)
    monkeypatch.setattr(processes, "REPOSITORY", tmp_path)

    def identity():
        processes.code_identity.cache_clear()
        return processes.code_identity()

    (tmp_path / "reports/a.md").write_text("a rebuilt report\n")
    assert identity()["commit_dirty"] == "false"  # a plan's report step rebuilt the checkout's reports
    (tmp_path / "conf/a.yaml").write_text("y\n")
    assert identity()["commit_dirty"] == "true"
    processes.code_identity.cache_clear()
