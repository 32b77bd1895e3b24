"""The Ch.6 robot report (hrc_lab/report/ch6_robot.py): the robot row's section (outcomes per part count, the
filmed episode, times in the CSV) and its thesis row, built from a store of logged runs."""

from __future__ import annotations

import re

import pandas as pd
import pytest
from omegaconf import OmegaConf

from hrc_lab.config import LoggerConfig
from hrc_lab.report.build import build_report
from hrc_lab.report.ch6_robot import PLAN
from hrc_lab.report.sections import SECTIONS, load_sections
from hrc_lab.tracking import RunTracker


def robot_runs(method: str = "gnn_att") -> pd.DataFrame:
    return pd.DataFrame({"method": [method] * 2, "seed": [0, 1], "cell": ["clutter"] * 2, "run_id": ["r0", "r1"],
                         "acc_3": [0.6, 0.8], "fail_slip_3": [0.1, 0.0], "fail_collision_3": [0.3, 0.2],
                         "fail_detection_3": [0.0, 0.0], "render_ms": [30.0, 32.0], "detection_ms": [50.0, 52.0],
                         "reasoning_ms": [6.0, 6.0], "motion_ms": [4000.0, 4200.0],
                         "perception_reasoning_ms": [86.0, 90.0], "param.protocol.cases": ["30"] * 2,
                         "param.protocol.choose_yaw": ["True"] * 2, "param.protocol.grip_depth": ["0.024"] * 2,
                         "video_scene": [float("nan"), 2.0], "param.protocol.video_objects": ["5"] * 2})


def test_the_robot_section_gives_each_outcome_per_part_count_and_the_filmed_episode():
    load_sections()
    section = SECTIONS["table_6_2_robot"](robot_runs())
    markdown = re.sub(r" +", " ", section.markdown)
    assert re.search(r"\| GNN_Att: delivered \| 0.700 ± 0.100 \|\n\| failed: detection \| 0.000 ± 0.000 \|\n"
                     r"\| failed: slip \| 0.050 ± 0.050 \|\n\| failed: collision \| 0.250 ± 0.050 \|", markdown)
    assert "30 scenes per part count" in markdown and "tips 0.024 m (`protocol.grip_depth`) deep" in markdown
    assert "perception and reasoning 88 ± 2 ms per iteration" in markdown
    assert "Video: seed 1, scene 2 with 5 parts" in markdown  # the one run that filmed an episode
    assert section.artifacts["robot_episode.mp4"] == ("r1", "videos/robot_episode.mp4")
    (result,) = section.results.to_dict("records")
    assert (result["row"], result["column"], result["n"]) == ("gnn_att", "3", 2)
    assert result["mean"] == pytest.approx(0.7)
    times = section.table.set_index("metric")
    assert times.loc["motion_ms", "mean"] == pytest.approx(4100.0) and "motion_ms" not in section.markdown


def log_robot_run(logger: LoggerConfig, seed: int, overrides: str, method: str, acc: float) -> None:
    """One finished run as ``hrc-lab experiment=ch6/table_6_2_robot`` logs it, of the study with ``overrides``."""
    study = next(s for s in PLAN.studies if " ".join(s.overrides) == overrides)
    tags = {"chapter": "ch6", "table": "table_6_2_robot", "experiment": "ch6/table_6_2_robot", "method": method,
            "cell": "clutter", "scenario": "clutter", "seed": str(seed), "sweep": "2026-12-08_00-00-00",
            "variant": study.variant, "variant_overrides": overrides, "overrides": f"seed={seed} {overrides}".strip()}
    with RunTracker(logger, "ch6/table_6_2_robot", f"ch6/table_6_2_robot-{method}-seed{seed}", tags) as tracker:
        tracker.log_config(OmegaConf.create({"name": "ch6/table_6_2_robot", "seed": seed,
                                             "protocol": {"cases": 30, "grip_depth": 0.024}}))
        tracker.log_metrics({f"acc_{n}": acc for n in (3, 4, 5, 6)} | {"perception_reasoning_ms": 90.0})


def test_the_report_puts_the_robot_row_and_the_star_study_beside_the_thesis(tmp_path):
    logger = LoggerConfig(tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}", artifact_root=str(tmp_path / "art"))
    star = " ".join(PLAN.study("robot_star").overrides)
    for seed in (0, 1, 2):
        log_robot_run(logger, seed, "", "gnn_att", 0.7 + seed / 100)
        log_robot_run(logger, seed, star, "gnn_rel_att_depth", 0.95)
    report = build_report(PLAN, logger.tracking_uri, tmp_path / "reports").read_text()
    opening = re.sub(r" +", " ", report.split("## The thesis' results beside ours")[1].split("\n## ")[0])
    assert "| Robot grasping | thesis | 0.91 | 0.87 | 0.78 | 0.68 |" in opening
    assert "| | [as written](#table_6_2_robot) | 0.71 ± 0.01 | 0.71 ± 0.01 | 0.71 ± 0.01 | 0.71 ± 0.01 |" in opening
    assert "| | [★ GNN_Rel_Att + depth, more scenes ✓](#robot_star) | 0.95 ± 0.00 |" in opening
    assert f"Reproduce: `{PLAN.study('robot_star').command}`" in report
    assert "## Table 6.2 (robot row) with ★ GNN_Rel_Att + depth on more training scenes" in report
