"""hrc-lab-reproduce: the plan covers every table and figure experiment, --dry-run prints it, a run stops at the
first failing step, and --check flags a cell only when it moves by more than its seed spread."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

from hrc_lab import reproduce
from hrc_lab.report.plans import PLANS
from hrc_lab.reproduce import LEFT_OUT, PLAN, Step, compare_reports, main

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def runs_folder(tmp_path, monkeypatch):
    """The journal of finished sweeps goes to a temporary runs folder, not the checkout's."""
    monkeypatch.setenv("HRC_LAB_RUNS", str(tmp_path / "runs"))
    return tmp_path / "runs"


def test_plan_covers_every_table_and_figure_experiment():
    experiments = {
        str(p.relative_to(ROOT / "conf/experiment").with_suffix("")) for p in ROOT.glob("conf/experiment/*/*.yaml")
    }
    planned = {arg.removeprefix("experiment=") for step in PLAN for arg in step.argv if arg.startswith("experiment=")}
    assert planned.isdisjoint(LEFT_OUT)
    assert experiments == planned | set(LEFT_OUT), "every experiment file is planned or left out with a reason"
    assert {step.topic for step in PLAN if step.kind == "report"} == set(PLANS)
    kinds = [step.kind for step in PLAN]
    assert kinds == sorted(kinds, key=["sweep", "report"].index), "every sweep runs before any report"


def test_dry_run_prints_every_step(capsys):
    assert main(["all", "--dry-run", "--tracking-uri", "http://127.0.0.1:5001"]) == 0
    out = capsys.readouterr().out
    for step in PLAN:
        assert step.name in out
    assert out.count("logger.tracking_uri=http://127.0.0.1:5001") == sum(step.kind == "sweep" for step in PLAN)
    assert out.count("--tracking-uri http://127.0.0.1:5001") == len(PLANS)
    assert main(["ch6", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [line.split("] ", 1)[1].split(": ", 1)[0] for line in lines]
    ch6 = [step for step in PLAN if step.topic.startswith("ch6")]
    assert names == [step.name for step in ch6 if step.kind == "sweep"] + ["report ch6_grasp", "report ch6_robot"]
    assert lines[0].startswith(f"[1/{len(ch6)}] sweep ch6/table_6_1: ")


def test_check_sends_the_demonstration_videos_to_the_fresh_folder_not_the_committed_one(capsys):
    assert main(["data", "--dry-run"]) == 0
    assert "publish_dir" not in capsys.readouterr().out
    assert main(["data", "--dry-run", "--check"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "experiment=data/render_demo" in line]
    assert len(lines) == 4
    assert all(line.endswith("'protocol.publish_dir=<temporary folder>/videos'") for line in lines)


def test_run_stops_at_the_first_failure(monkeypatch, capsys):
    fake = [
        Step("sweep ok", "sweep", "ch6_grasp", ("python", "-c", "print('first ran')")),
        Step("sweep broken", "sweep", "ch6_grasp", ("python", "-c", "raise SystemExit(3)")),
        Step("report never", "report", "ch6_grasp", ("python", "-c", "print('must not run')")),
    ]
    monkeypatch.setattr(reproduce, "PLAN", fake)
    assert main(["ch6"]) == 3
    captured = capsys.readouterr()
    assert "step 'sweep broken' failed (exit 3)" in captured.err
    summary = captured.out[captured.out.index("\nstep ") :]
    assert "sweep ok" in summary and "FAILED (exit 3)" in summary and "not run" in summary and "total" in summary
    assert "\nmachine: " in captured.out and " cores, torch kernels " in captured.out  # what the times depend on
    assert "must not run" not in captured.out


def _write(folder: Path, topic: str, table: pd.DataFrame) -> None:
    (folder / topic).mkdir(parents=True, exist_ok=True)
    table.to_csv(folder / topic / "table_x.csv", index=False)


def _table(ours_mean: float, rf_mean: float, latency: float = 1.0) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "method": ["ours", "rf"],
            "cell": ["3of5", "3of5"],
            "sr_mean": [ours_mean, rf_mean],
            "sr_std": [0.05, 0.02],
            "seeds": [5, 5],
            "latency_ms": [latency, latency],
        }
    )


def test_check_flags_a_cell_outside_its_spread_and_passes_one_inside(tmp_path):
    committed, fresh = tmp_path / "committed", tmp_path / "fresh"
    _write(committed, "ch4_reasoning", _table(0.80, 0.50))
    _write(fresh, "ch4_reasoning", _table(0.84, 0.60, latency=9.0))  # ours: +0.04 <= 0.05; rf: +0.10 > 0.02
    differences, _ = compare_reports(committed, fresh, ["ch4_reasoning"])
    assert len(differences) == 1, differences
    assert "('rf', '3of5', 0)" in differences[0] and "sr_mean" in differences[0]

    _write(fresh, "ch4_reasoning", _table(0.84, 0.51))
    assert compare_reports(committed, fresh, ["ch4_reasoning"])[0] == []


def test_check_parses_mean_plus_minus_std_and_exact_cells(tmp_path):
    committed, fresh = tmp_path / "committed", tmp_path / "fresh"
    for folder, sr, agree in (
        (committed, ["0.90 ± 0.05", "0.50 ± 0.01"], 0.95),
        (fresh, ["0.93 ± 0.02", "0.40 ± 0.01"], 0.94),
    ):
        _write(
            folder, "data_demonstrations", pd.DataFrame({"scenario": ["a", "b"], "sr": sr, "agreement": [agree, 1.0]})
        )
    differences, _ = compare_reports(committed, fresh, ["data_demonstrations", "ch3_rl"])
    assert len(differences) == 2, differences  # b's sr moved 0.10 > 0.01; a's agreement has no spread and changed
    assert any("('b', 0), sr" in d for d in differences) and any("('a', 0), agreement" in d for d in differences)


def test_check_run_exits_non_zero_when_a_fresh_report_differs(monkeypatch, tmp_path, capsys):
    committed = tmp_path / "committed"
    _write(committed, "ch6_grasp", _table(0.80, 0.50))
    write = (
        "import sys, pathlib, pandas as pd; out = pathlib.Path(sys.argv[sys.argv.index('--out') + 1]) / 'ch6_grasp'; "
        "out.mkdir(parents=True); pd.DataFrame({'method': ['ours', 'rf'], 'cell': ['3of5'] * 2, "
        "'sr_mean': [0.8, RF], 'sr_std': [0.05, 0.02], 'seeds': [5, 5], 'latency_ms': [2.0, 2.0]})"
        ".to_csv(out / 'table_x.csv', index=False)"
    )
    for rf_mean, expected in ((0.51, 0), (0.7, 1)):
        fake = [Step("report ch6_grasp", "report", "ch6_grasp", ("python", "-c", write.replace("RF", str(rf_mean))))]
        monkeypatch.setattr(reproduce, "PLAN", fake)
        assert (
            main(["ch6", "--check", "--committed", str(committed), "--out", str(tmp_path / f"fresh{expected}")])
            == expected
        )
        out = capsys.readouterr().out
        assert ("DIFFERS" in out) == bool(expected)


@pytest.mark.parametrize("selection", ["ch3", "ch4", "ch5", "ch6", "data"])
def test_every_chapter_has_steps(selection):
    steps = reproduce.select(PLAN, [selection])
    assert steps and steps[-1].kind == "report"
    # a report is rebuilt whole from its plan's runs: nothing is kept from an earlier report
    assert all(step.argv == ("hrc-lab-report", step.topic) for step in steps if step.kind == "report")
    assert all(Path(sys.executable).parent.joinpath(step.argv[0]).name.startswith("hrc-lab") for step in steps)


def test_check_lists_a_committed_table_the_fresh_report_lacks(tmp_path):
    """Every section is a study of the plan, so a committed table the fresh report does not have differs (an
    ablation is re-run like any other study)."""
    committed, fresh = tmp_path / "committed", tmp_path / "fresh"
    _write(committed, "ch3_motion", _table(0.8, 0.5))
    _write(fresh, "ch3_motion", _table(0.8, 0.5))
    _table(0.1, 0.1).to_csv(committed / "ch3_motion" / "table_3_1_extra.csv", index=False)
    differences, notes = compare_reports(committed, fresh, ["ch3_motion"])
    assert differences == ["ch3_motion/table_3_1_extra.csv: committed, but the fresh report has no such table"]
    assert notes == []


def test_every_study_of_every_plan_is_a_step_and_its_reproduce_line_is_that_step(capsys):
    """``--dry-run`` lists every section any report shows: each study's sweeps, with the command its section
    prints."""
    assert main(["all", "--dry-run"]) == 0
    out = capsys.readouterr().out
    for plan in PLANS.values():
        for study in plan.studies:
            for command in study.command.split(" && "):
                assert f": {command}\n" in out, command


def test_resume_skips_the_sweeps_an_earlier_reproduction_finished_and_counts_their_time(monkeypatch, capsys,
                                                                                         runs_folder, tmp_path):
    ran = tmp_path / "ran.txt"
    append = "import sys; open(sys.argv[1], 'a').write(sys.argv[2] + chr(10))"
    fake = [
        Step("sweep one", "sweep", "ch6_grasp", ("python", "-c", append, str(ran), "one")),
        Step("sweep two", "sweep", "ch6_grasp", ("python", "-c", append + "; raise SystemExit(int(sys.argv[3]))",
                                                 str(ran), "two", "1")),
        Step("report", "report", "ch6_grasp", ("python", "-c", append, str(ran), "report")),
    ]
    monkeypatch.setattr(reproduce, "PLAN", fake)
    assert main(["ch6"]) == 1  # "two" fails: only "one" is journaled
    assert ran.read_text().split() == ["one", "two"]
    fake[1] = Step("sweep two", "sweep", "ch6_grasp", fake[1].argv[:-1] + ("0",))
    capsys.readouterr()
    assert main(["ch6", "--resume"]) == 0
    assert ran.read_text().split() == ["one", "two", "two", "report"]  # "one" was not run again
    out = capsys.readouterr().out
    assert "sweep one: done " in out and "(--resume)" in out
    journal = (runs_folder / "reproduce.jsonl").read_text().splitlines()
    assert len(journal) == 2 and all('"cpu": ' in line for line in journal)
    assert main(["ch6"]) == 0  # without --resume every sweep runs
    assert ran.read_text().split()[-3:] == ["one", "two", "report"]


def test_a_signal_stops_the_whole_step_with_its_workers_and_the_summary_says_so(tmp_path, runs_folder):
    """SIGTERM (a cluster's time limit, `kill`) reaches the sweep's process group: the step handles it (a job marks
    its MLflow run KILLED), a launcher worker that outlives it (an idle joblib worker) is killed after the grace
    time, the summary shows the step as stopped and the later steps as not run, nothing is journaled, and the
    reproduction exits with the signal's code."""
    import os
    import signal
    import subprocess
    import time

    pid_file, handled = tmp_path / "worker.pid", tmp_path / "handled"
    worker = ("import os, signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
              f"open({str(pid_file)!r}, 'w').write(str(os.getpid())); time.sleep(120)")
    step = ("import signal, subprocess, sys, time\n"
            f"def stop(signum, frame):\n    open({str(handled)!r}, 'w').write('KILLED'); sys.exit(1)\n"
            "signal.signal(signal.SIGTERM, stop)\n"
            f"subprocess.Popen([sys.executable, '-c', {worker!r}]); time.sleep(120)\n")
    runner = ("import sys; from hrc_lab import reproduce; from hrc_lab.reproduce import Step; "
              "reproduce.STOP_GRACE_S = 1.0; "
              f"reproduce.PLAN = [Step('sweep stopped', 'sweep', 'ch6_grasp', ('python', '-c', {step!r})), "
              "Step('report ch6_grasp', 'report', 'ch6_grasp', ('python', '-c', 'pass'))]; "
              "sys.exit(reproduce.main(['ch6']))")
    reproduction = subprocess.Popen([sys.executable, "-c", runner], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True)
    deadline = time.monotonic() + 60
    while not (pid_file.exists() and pid_file.read_text()) and time.monotonic() < deadline:
        time.sleep(0.1)
    grandchild = int(pid_file.read_text())
    reproduction.send_signal(signal.SIGTERM)
    out, err = reproduction.communicate(timeout=30)
    assert reproduction.returncode == 128 + signal.SIGTERM
    assert handled.read_text() == "KILLED"
    assert "STOPPED (SIGTERM)" in out and "report ch6_grasp" in out and "not run" in out and "total" in out
    assert "stopped by SIGTERM during step 'sweep stopped'" in err
    assert not (runs_folder / "reproduce.jsonl").exists()
    for _ in range(100):
        try:
            os.kill(grandchild, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        pytest.fail("the step's worker outlived the reproduction")
