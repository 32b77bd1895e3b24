"""Report sections: one builder per table or figure (keyed by the ``table`` tag of its runs), and the topics
(report files) that gather them."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import pandas as pd

from hrc_lab.report.thesis import seeds_of


@dataclass
class Section:
    title: str
    markdown: str
    table: pd.DataFrame
    figures: dict = field(default_factory=dict)  # file name -> matplotlib figure
    artifacts: dict = field(default_factory=dict)  # file name -> (MLflow run id, artifact path) to copy
    sources: str = ""  # which sweeps (and variant) the section read, set by hrc_lab.report.build.section_of


SECTIONS: dict[str, Callable[[pd.DataFrame], Section]] = {}


def register_section(table: str):
    """Register ``builder(runs) -> Section`` as the section of the runs tagged ``table``. It renders inside
    :func:`hrc_lab.report.thesis.seeds_of`, so that a section built from one seed prints its cells without a
    spread."""

    def decorator(builder):
        @functools.wraps(builder)
        def build(runs: pd.DataFrame) -> Section:
            with seeds_of(runs):
                return builder(runs)

        SECTIONS[table] = build
        return build

    return decorator


# report file -> (title, where the data comes from, [(MLflow experiment, table tag), ...])
TOPICS = {
    "ch4_reasoning": (
        "Ch.4 reasoning module (GraphSAGE importance ranking) vs. baselines",
        "Our scenes come from the simulator-independent package-to-order spec (`hrc_lab/env/robot/spec.py`), "
        "not the thesis' CoppeliaSim scenes.",
        [
            ("ch4/table_4_1", "table_4_1"),
            ("ch4/fig_4_7", "fig_4_7"),
            ("ch4/practical", "practical"),
            ("ch4/fig_4_9", "fig_4_9"),
        ],
    ),
    "ch3_motion": (
        "Ch.3 two-level LfD motion planner: error correction (Table 3.1) and the neural dynamic planner (Fig. 3.10)",
        "Trials run in our robosuite UR5e error-correction cells (`hrc_lab/env/robot/correction_cell.py`), not the "
        "thesis' CoppeliaSim UR10; demonstrations come from the scripted expert (how many per case and seed: each "
        "section, read from its runs), segmented into stages by PELT change points (`hrc_lab/data/segmentation.py`), "
        "with re-sampled sub-goals per stage. "
        "The neural dynamic planner sees Δ = s − r in the arm's base frame (radial, tangential, vertical).",
        [("ch3/table_3_1", "table_3_1"), ("ch3/fig_3_10", "fig_3_10")],
    ),
    "ch3_rl": (
        "Ch.3 hybrid hierarchical guided RL (Algorithm 1): DDPG + HER guided by the two-level planner",
        "Training runs in our robosuite UR5e error-correction cells (`hrc_lab/env/robot/correction_cell.py`) as a "
        "gymnasium goal env (`hrc_lab/rl/goal_env.py`), not the thesis' CoppeliaSim UR10; the agent is "
        "stable-baselines3's DDPG with its HER replay buffer (`hrc_lab/rl/agent.py`), the guide the two-level planner "
        "trained on scripted-expert demonstrations (`hrc_lab/experiments/ch3_motion.py`). Algorithm 1 runs one "
        "episode and one update per epoch; our epoch is in each section (`hrc_lab/experiments/ch3_rl.py`). "
        "Throughput of the goal env and of training, before and after the lean step and the reference's cycle, "
        "measured side by side in one run: [ch3_rl/throughput.md](ch3_rl/throughput.md) "
        "(`python scripts/bench_rl_throughput.py --out reports/ch3_rl/throughput.md`).",
        [("ch3/fig_3_13", "fig_3_13"), ("ch3/fig_3_12", "fig_3_12"), ("ch3/fig_3_9", "fig_3_9"), ("rl/fetch", "fetch")],
    ),
    "ch4_motion": (
        "Ch.4 motion module: task-conditioned sub-goal planner and neural dynamic planner vs. VI, GPR, MLP",
        "Closed-loop trials run in our robosuite UR5e cell (`hrc_lab/env/robot/`), not the thesis' CoppeliaSim UR10; "
        "demonstrations come from the scripted expert (how many per cell and seed: the section, read from its runs; "
        "3 designed sub-goals per stage, `hrc_lab.motion.two_level.DESIGNED_SUBGOALS`). The "
        "neural dynamic planner sees Δ = s − r in the arm's base frame (radial, tangential, vertical; the thesis does "
        "not name the frame).",
        [("ch4/table_4_2", "table_4_2")],
    ),
    "ch4_tamp": (
        "Ch.4 TAMP in the robot cell (Algorithm 2): ours vs DRL vs RM+RRT-Connect",
        "Trials run in our robosuite UR5e cell (`hrc_lab/env/robot/`), not the thesis' CoppeliaSim UR10, so "
        "execution time is simulated (control steps / control rate), not a UR10's. RRT-Connect is OMPL's "
        "(`hrc_lab/motion/rrt_connect.py`), planning in the 3-D joint space the neural dynamic planner acts in "
        "(base, shoulder, elbow; the wrist keeps the tool down) with MuJoCo collision checking; DRL is "
        "stable-baselines3's DDPG with its HER buffer on our goal env (`hrc_lab/rl/`).",
        [("ch4/table_4_3", "table_4_3")],
    ),
    "ch5_planner": (
        "Ch.5 graph semantic planner: goal inference, next object and text plans",
        "Our scenarios come from the assemble-to-order domain (`hrc_lab/env/assembly/spec.py`) with our own three "
        "goal configurations (`conf/env/ato.yaml`; the thesis' Fig. 5.4 is not legible in its text).",
        [("ch5/fig_5_7", "fig_5_7"), ("ch5/table_5_2_planner", "table_5_2_planner")],
    ),
    "ch5_perception": (
        "Ch.5 hand-centric action detector and the video-to-plan pipeline",
        "Videos are generated (`hrc_lab/env/assembly/video.py`): a top-down view of our assembly cell with a right "
        "hand drawn by OpenCV that MediaPipe detects, performing the 18 actions of Table 5.1 along noisy human-like "
        "paths with varied speed, skin tone, hand size, light and table colour; not the thesis' RealSense recordings "
        "of a real worker. MediaPipe 0.10.21 (lite landmark model) tracks the hand; every network trains from "
        "scratch on CPU (no pretrained VGG16).",
        [("ch5/fig_5_6", "fig_5_6"), ("ch5/table_5_2", "table_5_2")],
    ),
    "ch5_hrc": (
        "Ch.5 human-robot collaboration with the robot in the loop (Algorithm 3's PickandPlace)",
        "The worker is a generated video (`hrc_lab/env/assembly/video.py`), not a person on a RealSense camera; the "
        "robot is a simulated UR5e with a suction cup in robosuite (`hrc_lab/env/robot/assembly_cell.py`), not the "
        "thesis' UR10 at a real bench; part shapes are cuboids of three sizes. Every network trains from scratch "
        "on CPU.",
        [("ch5/hrc_session", "hrc_session")],
    ),
    "ch6_grasp": (
        "Ch.6 iterative visual grasping: graspability and grasp solutions from detector features",
        "Scenes are rendered in MuJoCo (parts a, b, c dropped with physics, top-down camera; "
        "`hrc_lab/env/clutter/scenes.py`), not the thesis' photos of real parts; labels come from one geometric "
        "rule for a top-down grasp with a fixed gripper orientation (`hrc_lab/env/clutter/rule.py`), not a human "
        "expert; the detector is a small Faster R-CNN trained from scratch on the rendered scenes, not a "
        "pretrained ResNet-101-FPN.",
        [("ch6/table_6_1", "table_6_1"), ("ch6/table_6_2_single", "table_6_2_single"), ("ch6/table_6_3", "table_6_3"),
         ("ch6/fig_6_9", "fig_6_9")],
    ),
    "ch6_robot": (
        "Ch.6 iterative grasping with the robot (Algorithm 4 in a robosuite clutter cell)",
        "The scenes are Table 6.2's rendered ones (`hrc_lab/env/clutter/scenes.py`), placed in a robosuite cell with a "
        "simulated UR5e and robosuite's Robotiq 2F-140 (`hrc_lab/env/robot/clutter_cell.py`), not the thesis' UR10 "
        "with a 2F-85 at real parts; the camera is the scenes' own, rendered with depth. The detector and solver "
        "train from scratch on CPU, as in the single-image row.",
        [("ch6/table_6_2_robot", "table_6_2_robot")],
    ),
    "data_demonstrations": (
        "Robot cells and scripted-expert demonstrations (Ch.3, Ch.4)",
        "robosuite 1.5.1 UR5e with our suction cup on MuJoCo 3.9.0 (`hrc_lab/env/robot/`), not the thesis' CoppeliaSim "
        "UR10; demonstrations come from a scripted expert (`hrc_lab/env/robot/expert.py`), not keyboard teleoperation. "
        "One rendered demonstration per cell (`hrc-lab experiment=data/render_demo env=<env> [env.sim.case=2]`) is "
        "in [videos/](videos/): packing a 4-of-5 order and a 3-of-5 order after a human packed part of it "
        "(CASE 2), correcting one misplaced cuboid and two cuboids where red occupies blue's place.\n\n"
        "![4of5](videos/4of5_strip.jpg)\n![3of5 CASE 2](videos/3of5_case2_strip.jpg)\n"
        "![one object, case 1](videos/one_object_case1_strip.jpg)\n"
        "![two objects, case 2](videos/two_object_case2_strip.jpg)",
        [("data/collect_ch4", "collect_ch4"), ("data/collect_ch3", "collect_ch3")],
    ),
}


def load_sections() -> None:
    from hrc_lab.report import (  # noqa: F401  (registration)
        ch3_motion,
        ch3_rl,
        ch4_motion,
        ch4_reasoning,
        ch4_tamp,
        ch5_hrc,
        ch5_perception,
        ch5_planner,
        ch6_grasp,
        ch6_robot,
        data,
    )
