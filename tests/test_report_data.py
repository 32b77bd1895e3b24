"""The demonstrations report (hrc_lab/report/data.py): a tiny Ch.3 collect job end to end, its section linking the
rendered video of its scenario, and the plan's videos as render steps."""

from __future__ import annotations

import re

from hrc_lab.config import validate_config
from hrc_lab.report.data import PLAN, VIDEOS


def test_collect_ch3_job_end_to_end(run_job, job_report):
    job = run_job("experiment=data/collect_ch3", "hydra.mode=RUN", "env=error_correction_one_object_case1",
                  "protocol.episodes=2")
    report = job_report(job, "data_demonstrations")
    section = re.sub(r" +", " ", report.split("## collect_ch3 (this test's settings)")[1].split("\n## ")[0])
    sr = job.metrics["expert_success_rate"]
    assert f"| one_object_case1 | 0 | {sr:.2f} | 2 |" in section
    assert "2 scripted-expert episodes per error-correction scenario" in section
    assert "the thesis: 20 keyboard-teleoperated demonstrations per case" in section  # thesis_results.yaml
    assert "δr 0.06 m (`env.sim.success_threshold`)" in section
    assert "![one_object_case1](videos/one_object_case1_strip.jpg)" in section  # a scenario the plan films
    assert "two_object_case2" not in section  # filmed, but not among this job's scenarios
    assert "## The thesis' results beside ours" not in report  # no thesis table
    assert "## collect_ch4\n\nNot run yet: `hrc-lab experiment=data/collect_ch4 hydra/launcher=joblib`" in report


def test_each_video_the_sections_link_is_named_as_its_render_step_names_it(compose_config):
    """``data/render_demo`` writes ``<env.scenario>.mp4``: each plan step's scenario is the name the sections link."""
    assert len(PLAN.extra) == len(VIDEOS)
    for scenario, step in zip(VIDEOS, PLAN.extra, strict=True):
        assert validate_config(compose_config(*step)).env.scenario == scenario, step
