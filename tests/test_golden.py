"""Golden metrics: one tiny job per chapter at a fixed seed, its final metrics committed in ``tests/golden/<name>.json``
and compared here, so that a change that moves a number is seen (issue "One reproduction, and reports a person can
read", item 5). A refactor or a speed-up must leave every golden file as it is.

Changing a golden file means the code now computes something else: re-run that chapter's plan
(``hrc-lab-reproduce <chapter>``), commit its rebuilt reports, then rewrite the file with
``HRC_LAB_UPDATE_GOLDEN=1 .venv/bin/python -m pytest tests/test_golden.py``. Wall-clock metrics (latencies, times,
speeds) are machine readings, not results: they are not compared."""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import pytest

GOLDEN = Path(__file__).parent / "golden"
# names of metrics that read a clock: never compared
WALL_CLOCK = re.compile(r"(latency|_ms\b|_ms_|_s$|_s_|seconds|per_s|per_min|wall|time|fps)")
REL, ABS = 1e-6, 1e-9  # float rounding across CPUs of the pinned kernel set (hrc_lab.kernels) stays far below

# name -> the hrc-lab overrides of its tiny job (hydra.mode=RUN: one job, no sweep)
JOBS = {
    "ch3_fig_3_13": ["experiment=ch3/fig_3_13", "hydra.mode=RUN", "env=error_correction_one_object_case1", "seed=0",
                     "rl.lam=0.7", "trainer.max_epochs=1", "motion.steps=10", "motion.ndp.steps=10",
                     "motion.classifier.steps=10", "protocol.demos=2", "protocol.epochs=2", "rl.cycles_per_epoch=1",
                     "rl.episodes_per_cycle=1", "rl.gradient_steps=8", "protocol.eval_episodes=1",
                     "rl.steps_per_subtask=8", "rl.learning_starts=8", "rl.batch_size=8", "rl.demo_batch_size=2",
                     "rl.net_arch=[16]", "rl.buffer_size=200"],
    "ch3_table_3_1": ["experiment=ch3/table_3_1", "hydra.mode=RUN", "env=error_correction_two_object_case1",
                      "motion=tc_vi_object", "seed=0", "trainer.max_epochs=1", "motion.steps=20",
                      "motion.ndp.steps=20", "motion.classifier.steps=20", "protocol.demos=2", "protocol.trials=2"],
    "ch4_table_4_1": ["experiment=ch4/table_4_1", "hydra.mode=RUN", "env=package_to_order_3of5", "reasoning=ours",
                      "seed=0", "trainer.max_epochs=1", "reasoning.steps=20", "protocol.min_demos=10"],
    "ch4_table_4_3": ["experiment=ch4/table_4_3", "hydra.mode=RUN", "env=package_to_order_2of3", "tamp=ours",
                      "seed=0", "trainer.max_epochs=4", "protocol.trials=2", "protocol.min_demos=40",
                      "reasoning.steps=200", "protocol.demos=2", "motion.steps=10", "motion.ndp.steps=10",
                      "protocol.max_steps_per_subgoal=3", "protocol.video_cells=[]"],
    "ch4_table_4_3_drl": ["experiment=ch4/table_4_3", "hydra.mode=RUN", "env=package_to_order_2of3", "tamp=drl",
                          "seed=0", "trainer.max_epochs=1", "protocol.trials=2", "protocol.min_demos=10",
                          "protocol.drl_iterations=2", "rl.cycles_per_epoch=1", "rl.episodes_per_cycle=1",
                          "rl.gradient_steps=4", "protocol.drl_demos=1", "rl.demo_batch_size=2",
                          "protocol.drl_eval_episodes=1", "rl.steps_per_subtask=4", "rl.learning_starts=4",
                          "rl.batch_size=8", "rl.net_arch=[16]", "rl.buffer_size=500", "rl.bc_pretrain_steps=4",
                          "rl.critic_warmup_steps=2", "protocol.video_cells=[]"],
    "ch5_fig_5_7": ["experiment=ch5/fig_5_7", "hydra.mode=RUN", "env=ato_2goals", "seed=0", "trainer.max_epochs=4",
                    "reasoning.steps=200", "protocol.ratios=[0.5,1.0]", "protocol.train_counts=[20]"],
    "ch6_table_6_1": ["experiment=ch6/table_6_1", "hydra.mode=RUN", "grasp=gnn_att", "seed=0", "trainer.max_epochs=1",
                      "grasp.steps=2", "grasp.detector.steps=2", "grasp.detector.width=4",
                      "grasp.detector.fpn_channels=8", "grasp.detector.representation_size=16",
                      "protocol.train_images=4"],
    "data_collect": ["experiment=data/collect", "hydra.mode=RUN", "env=error_correction_one_object_case2",
                     "protocol.episodes=2", "seed=0"],
}


def compared(metrics: dict[str, float]) -> dict[str, float]:
    return {key: float(value) for key, value in sorted(metrics.items()) if not WALL_CLOCK.search(key)}


def differences(golden: dict[str, float], fresh: dict[str, float]) -> list[str]:
    found = [f"{key}: only in the golden file" for key in golden.keys() - fresh.keys()]
    found += [f"{key}: new metric" for key in fresh.keys() - golden.keys()]
    for key in sorted(golden.keys() & fresh.keys()):
        a, b = golden[key], fresh[key]
        if not ((math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=REL, abs_tol=ABS)):
            found.append(f"{key}: golden {a!r}, now {b!r}")
    return found


@pytest.mark.parametrize("name", sorted(JOBS))
def test_a_tiny_job_per_chapter_computes_its_golden_metrics(name, run_job):
    job = run_job(*JOBS[name])
    fresh = compared(job.metrics)
    path = GOLDEN / f"{name}.json"
    if os.environ.get("HRC_LAB_UPDATE_GOLDEN") == "1":
        GOLDEN.mkdir(exist_ok=True)
        path.write_text(json.dumps({"overrides": JOBS[name], "metrics": fresh}, indent=1, sort_keys=True) + "\n")
    recorded = json.loads(path.read_text())
    assert recorded["overrides"] == JOBS[name], f"{path.name} was written for other overrides; rewrite it"
    moved = differences(recorded["metrics"], fresh)
    assert not moved, (f"{name}: the code computes other numbers than {path} records; if that is intended, re-run "
                       "the chapter's plan and rewrite the file (this module's docstring):\n  " + "\n  ".join(moved))


def test_a_moved_metric_is_named_and_wall_clock_ones_are_not_compared():
    assert compared({"sr": 1, "planning_ms_per_object": 2, "train_s": 3, "latency_ms_batch1": 4}) == {"sr": 1.0}
    assert differences({"sr": 0.5, "oa": 0.25}, {"sr": 0.5, "oa": 0.5}) == ["oa: golden 0.25, now 0.5"]
    assert differences({"sr": float("nan")}, {"sr": float("nan")}) == []
