"""The Ch.5 HRC report (hrc_lab/report/ch5_hrc.py): Table 5.2 with the robot in the loop, as Algorithm 3 is written
and with hrc_lab's ★ recovery, from runs logged as ``ch5/hrc_session`` logs them (metrics and per-session tables)."""

from __future__ import annotations

import re

import pandas as pd
from test_report_ch5_perception import log_ch5_run, logger  # noqa: F401 (logger: the fixture)

from hrc_lab.report.build import build_topic


def log_hrc(store, cell: str, complete: list[bool], recoveries: list[int], overrides: tuple[str, ...] = (),
            sc: float = 0.7) -> None:
    """One ``ch5/hrc_session`` job (its config the default one) whose tables hold two sessions: session 0 right at
    every step, session 1 with a wrong guidance (and no screw: its SC is NaN); the robot asked for help once where a
    session did not end assembled."""
    recovery = bool(overrides)
    metrics = {"ad_acc": 0.9, "sg_acc": 0.8, "sc_acc": sc, "robot_commands": 2.0, "robot_refused_rate": 0.5,
               "robot_placement_sr": 1.0, "complete_rate": sum(complete) / 2, "recoveries_per_session": 0.5,
               "n_sessions": 2.0, "n_fast_sessions": 0.0, "screw_latency_ms": 30.0, "classify_ms": 8.0,
               "tracking_ms_per_frame": 7.0, "pick_place_sim_s": 2.4, "pick_place_wall_s": 0.3,
               "filmed_session": 1.0 if recovery else 0.0}
    sessions = pd.DataFrame({"session": [0, 1], "fast": [False, False], "sg_acc": [1.0, 0.5],
                             "sc_acc": [1.0, float("nan")], "complete": complete, "recoveries": recoveries})
    help_rows = [] if all(complete) else [{"session": 1, "reason": "robot o1->p3: p3 is occupied by o2"}]
    log_ch5_run(store, "ch5/hrc_session", cell, 0, metrics, "hand_lstm_fcn", overrides,
                config={"env": {"robot": {"place_tolerance": 0.02}},
                        "protocol": {"sessions": 7, "recovery": recovery}},
                tables={"hrc_sessions": sessions, "robot_help": pd.DataFrame(help_rows, columns=["session", "reason"])},
                files={"videos": "session_side_by_side.mp4"})


def test_table_5_2_with_the_robot_as_written_and_with_the_recovery(logger, tmp_path):  # noqa: F811
    for cell, complete in (("1goal", [True, True]), ("3goals", [True, False])):
        log_hrc(logger, cell, complete, [0, 0])
    log_hrc(logger, "1goal", [True, True], [0, 1], ("protocol.recovery=True",), sc=0.95)
    out = tmp_path / "report"
    text = build_topic("ch5_hrc", logger.tracking_uri, out).read_text()
    opening = re.sub(r" +", " ", text.split("## The thesis' results beside ours")[1].split("\n## ")[0])
    opening = opening.replace("|  |", "| |")
    assert "| 1 goal | thesis | 98.30 ± 1.20 | 97.30 ± 1.20 | 95.30 ± 1.20 |" in opening
    assert "| | [as written (1 seed)](#hrc_session) | 90.00 | 80.00 | 70.00 |" in opening
    assert "| | [★ recovery (1 seed)](#recovery) | 90.00 | 80.00 | 95.00 |" in opening
    assert "| 3 goals | thesis |" in opening and "| | [★ recovery](#recovery) | – | – | – |" in opening

    default = re.sub(r" +", " ", text.split("## The HRC loop with the robot: Table 5.2 extended")[1].split("\n## ")[0])
    assert "| 3 | 90.0 | 80.0 | 70.0 | 50.0 | 100.0 | 50.0 |" in default  # one seed: no spread
    assert "first 7 sessions per seed" in default and "within 0.02 m" in default
    assert "recoveries" not in default and "★" not in default
    assert "Video: session 0 of `1goal`, seed 0 (it ends assembled)" in default
    csv = pd.read_csv(out / "ch5_hrc" / "hrc_session.csv").set_index("metric")
    # session 0 of each run was right at every step (2, both assembled), session 1 had an error (1 of 2 assembled)
    assert csv.loc["sessions_right", "mean"] == 2 and csv.loc["assembled_of_right", "mean"] == 2
    assert csv.loc["sessions_with_error", "mean"] == 2 and csv.loc["assembled_of_with_error", "mean"] == 1
    assert csv.loc["help: robot o<i>->p<k>: p<k> is occupied by o2", "mean"] == 1
    assert (out / "ch5_hrc" / "hrc_session.mp4").exists() and (out / "ch5_hrc" / "recovery.csv").exists()

    star = re.sub(r" +", " ", text.split("## ★ The HRC loop with the robot")[1])
    assert "★ Recovery (hrc_lab's, beyond Algorithm 3)" in star and "| 1 | 90.0 | 80.0 | 95.0 |" in star
    assert "recoveries / session" in star and "| 0.50 |" in star
    assert "Video: session 1 of `1goal`, seed 0 (with a recovery, it ends assembled)" in star
    assert "Reproduce: `hrc-lab experiment=ch5/hrc_session protocol.recovery=True hydra/launcher=joblib`" in star
