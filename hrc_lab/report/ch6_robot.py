"""Report section of Algorithm 4 with the robot (thesis 6.4.1, Fig. 6.8): the robot row of Table 6.2 in the
robosuite clutter cell, each episode's outcome (delivered, or the first cause of its failure) per part count, and a
filmed episode; where an iteration's time goes is in the CSV. Its own report, as the Ch.5 loop with the robot is, so
that it is rebuilt without re-running Table 6.1's studies."""

from __future__ import annotations

import re

import pandas as pd

from hrc_lab.grasp.diagnostics import ROBOT_FAILURES
from hrc_lab.report.ch6_grasp import METHODS, STAR
from hrc_lab.report.headline import results_frame
from hrc_lab.report.plan import Pick, Plan, Row, Study
from hrc_lab.report.runs import amount, keyed, over_seeds, setting, spread
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, markdown_table

VIDEO = ("robot_episode.mp4", "robot_episode_strip.jpg")  # a run's artifacts under videos/
PHASES = ("render", "detection", "reasoning", "motion")  # <phase>_ms: mean per iteration (motion: per grasp and put)


def _record(runs: pd.DataFrame, metric: str, column: str) -> dict:
    mean, std = spread(runs, metric)
    n = int(runs[metric].notna().sum()) if metric in runs else 0
    return {"metric": metric, "column": column, "mean": mean, "std": std, "n": n}


@register_section("table_6_2_robot")
def table_6_2_robot(runs: pd.DataFrame) -> Section:
    counts = sorted(int(c[len("acc_"):]) for c in runs.columns if re.fullmatch(r"acc_\d+", c))
    methods = [m for m in METHODS if m in set(runs.method)]
    records = []
    for method in methods:
        part = runs[runs.method == method]
        records += [{"method": method} | _record(part, f"acc_{n}", str(n)) for n in counts]
        records += [{"method": method} | _record(part, f"fail_{cause}_{n}", str(n))
                    for cause in ROBOT_FAILURES for n in counts if f"fail_{cause}_{n}" in part]
        records += [{"method": method} | _record(part, f"{key}_ms", "") for key in (*PHASES, "perception_reasoning")]
    frame = pd.DataFrame(records)
    rows = []
    for method in methods:
        mine = frame[frame.method == method].set_index("metric")
        outcomes = [("acc", f"{METHODS[method]}: delivered")]
        outcomes += [(f"fail_{cause}", f"failed: {cause}") for cause in ROBOT_FAILURES
                     if any(f"fail_{cause}_{n}" in mine.index for n in counts)]
        for stem, name in outcomes:
            rows.append({"episodes": name} | {
                f"{n} objects": fmt(*mine.loc[f"{stem}_{n}", ["mean", "std"]], 3) if f"{stem}_{n}" in mine.index
                else fmt(None) for n in counts})
    perception = spread(runs, "perception_reasoning_ms")
    text = [
        "Algorithm 4 with the robot on the single-image row's scenes and requests "
        f"({amount(runs, 'protocol.cases', 'scenes')} per part count): image, detect, read the graph, grasp the "
        "named part at its box's 3-D point (yaw from the depth image: "
        f"`protocol.choose_yaw` {setting(runs, 'protocol.choose_yaw')}; tips "
        f"{keyed(runs, 'protocol.grip_depth', 'm')} deep); a delivered part of the requested type succeeds. "
        f"{over_seeds(runs, start=True)}; failures by first cause; perception and reasoning {fmt(*perception, 0)} "
        "ms per iteration.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    artifacts = {}
    filmed = runs[runs.video_scene.notna()].sort_values("seed") if "video_scene" in runs else runs.iloc[:0]
    if len(filmed):  # the first successful episode of the protocol's video part count, filmed again from the side
        shown = filmed.iloc[0]
        text += ["", f"Video: seed {shown.seed}, scene {int(shown.video_scene)} with "
                     f"{amount(runs, 'protocol.video_objects', 'parts')}, the first delivered episode of that count."]
        artifacts = {name: (shown.run_id, f"videos/{name}") for name in VIDEO}
    results = results_frame([{"row": r["method"], **r} for r in records if r["metric"].startswith("acc_")])
    return Section("Table 6.2 (robot row): Algorithm 4 with the robot", "\n".join(text), frame, {}, artifacts,
                   results=results)


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch6_robot",
    title="Ch.6 iterative grasping with the robot (Algorithm 4 in a robosuite clutter cell)",
    note="Table 6.2's rendered scenes in a robosuite cell with a simulated UR5e and a Robotiq 2F-140, not the "
         "thesis' UR10 with a 2F-85 at real parts; the camera is the scenes' own, rendered with depth.",
    studies=(
        Study("ch6/table_6_2_robot"),
        Study("ch6/table_6_2_robot", (f"grasp={STAR}", "protocol.train_images=3416"), key="robot_star", star=True,
              title="Table 6.2 (robot row) with ★ GNN_Rel_Att + depth on more training scenes"),
    ),
    rows=(
        Row("Table 6.2", "Robot grasping", "ch6.table_6_2.robot_grasping", Pick("table_6_2_robot", "gnn_att"),
            star=Pick("robot_star", STAR, "GNN_Rel_Att + depth, more scenes"),
            why="a simulated UR5e and 2F-140, not a UR10 and 2F-85; the solver as in Table 6.1"),
    ),
)
