"""Report section of Algorithm 4 with the robot (thesis 6.4.1, Fig. 6.8): the robot row of Table 6.2 in the
robosuite clutter cell, with the causes of failed episodes, where an iteration's time goes and a filmed episode. Its
own report, as the Ch.5 loop with the robot is, so that it is rebuilt without re-running Table 6.1's ablations."""

from __future__ import annotations

import pandas as pd

from hrc_lab.grasp.diagnostics import ROBOT_FAILURES
from hrc_lab.report.ch6_grasp import METHODS
from hrc_lab.report.plan import Plan, Study
from hrc_lab.report.runs import NOT_LOGGED, amount, over_seeds, setting, spread
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, markdown_table, thesis_results, thesis_value

ROBOT_FAILURES_TEXT = (
    "*detection*, *graspability*, *solution*, *other*: the single-image answer of an iteration was wrong, judged "
    "against the rule on the scene as it then was (as in the single-image row); *slip*: the gripper closed on the "
    "named part and nothing rose with it (it may have pushed the part); *collision*: the gripper moved a neighbour "
    "(not the named part) by more than 5 mm and the grasp failed; *iteration_bound*: `protocol.max_grasps` grasps "
    "without a delivery."
)


def _opening(runs: pd.DataFrame) -> str:
    """How the runs' fingers open before a grasp (``protocol.preshape``)."""
    value = setting(runs, "protocol.preshape")
    if value == NOT_LOGGED:
        return "the fingers fully open (runs before `protocol.preshape`)"
    if value.lower() == "true":
        return ("the fingers opened only to the part's width plus the rule's finger gap and 5 mm "
                "(`protocol.preshape`; fully open, the 2F-140's pads stand ~6 cm either side)")
    return "the fingers fully open (`protocol.preshape=false`)" if value.lower() == "false" else f"preshape {value}"


def _approach(runs: pd.DataFrame) -> str:
    """At which yaw the gripper comes down (``protocol.choose_yaw``)."""
    value = setting(runs, "protocol.choose_yaw")
    if value.lower() == "true":
        first = ("the smallest turn first, the rule's yaw whenever it is clear" if setting(
            runs, "protocol.yaw_order") == "smallest_turn" else "the narrowest opening first")
        return ("turned to the yaw, of 12, whose finger volumes the depth image shows clear of neighbours, "
                f"{first} (`protocol.choose_yaw`, `protocol.yaw_order`)")
    return "its fingers closing along x as the rule's (" + (
        "runs before `protocol.choose_yaw`)" if value == NOT_LOGGED else "`protocol.choose_yaw=false`)")


def _grip(runs: pd.DataFrame) -> str:
    """How deep below the part's top the finger tips go (``protocol.grip_depth``)."""
    value = setting(runs, "protocol.grip_depth")
    if value == NOT_LOGGED:
        return ("the finger tips 8 mm below the part's top, the rule's `env.grasp_depth`, the gripper tilted 2.6 "
                "degrees (runs before `protocol.grip_depth`; in them a grasp that only pushed the named part counts "
                "as a collision)")
    return (f"the finger tips up to {float(value) * 1000:g} mm below the part's top (`protocol.grip_depth`), 2 mm "
            "above whatever the depth image shows in the fingers' way")


@register_section("table_6_2_robot")
def table_6_2_robot(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch6"]["table_6_2"]
    counts = sorted(int(c[len("acc_") :]) for c in runs.columns if c.startswith("acc_"))
    methods = sorted(set(runs.method)) if "method" in runs else ["gnn_att"]
    named = "ours, GNN_Att" if methods == ["gnn_att"] else ", ".join(METHODS.get(m, m) for m in methods)
    row = {"row": f"robot grasping ({named})"}
    records = []
    for count in counts:
        mean, std = spread(runs, f"acc_{count}")
        ref = thesis_value(thesis["robot_grasping"], thesis["columns"], count)  # None: a count it did not run
        row[f"{count} objects"] = f"{fmt(mean, std, 3)} ({'–' if ref is None else ref})"
        records.append({"objects": count, "mean": mean, "std": std, "thesis": ref})
    causes = sorted({c.split("_", 1)[1].rsplit("_", 1)[0] for c in runs.columns if c.startswith("fail_")},
                    key=lambda c: ROBOT_FAILURES.index(c) if c in ROBOT_FAILURES else len(ROBOT_FAILURES))
    failures = [{"failed because": cause} | {f"{n} objects": fmt(*spread(runs, f"fail_{cause}_{n}"), 3)
                                             for n in counts} for cause in causes]
    phases = [{"phase": name, "ms per iteration": fmt(*spread(runs, f"{key}_ms"), 1)}
              for key, name in (("render", "render (camera image + depth)"), ("detection", "detection + graph input"),
                                ("reasoning", "graph + solver (Algorithm 4 on the image)"),
                                ("motion", "robot motion (per grasp and put, simulated)"))]
    perception = spread(runs, "perception_reasoning_ms")
    text = [
        "Algorithm 4 with the robot: the single-image row's scenes and requested types "
        f"({amount(runs, 'protocol.cases', 'scenes')} per part count, the same seeds and draws) placed in the "
        "robosuite cell (UR5e, Robotiq 2F-140; `hrc_lab/env/robot/clutter_cell.py`). Each iteration images the "
        "scene, detects, reads the graph until the single-image answer, and grasps the part it names at the 3-D "
        f"point of its box (depth image + camera model), {_opening(runs)}, {_approach(runs)}, {_grip(runs)}: a part "
        "of the requested type goes to the tray and the episode succeeds; another part is put aside and the scene "
        "imaged again. An episode that ends in help succeeds when the rule's own Algorithm 4 also ends in help. "
        f"{over_seeds(runs, start=True)}; thesis (real UR10, 10 cases per count) in brackets; the single-image row "
        "is in [ch6_grasp.md](ch6_grasp.md).",
        "",
        pd.DataFrame([row]).to_markdown(index=False),
        "",
        f"Why episodes failed (share of all episodes per part count, {over_seeds(runs, listed=False)}; the first "
        f"cause that applies): {ROBOT_FAILURES_TEXT}",
        "",
        markdown_table(pd.DataFrame(failures)),
        "",
        f"Where the time goes (mean over iterations; perception and reasoning together {fmt(*perception, 1)} ms per "
        "iteration on this CPU; hrc_lab's real-time budget, 200 ms):",
        "",
        markdown_table(pd.DataFrame(phases)),
    ]
    artifacts = {}
    filmed = runs[runs.video_scene.notna()].sort_values("seed") if "video_scene" in runs else runs.iloc[:0]
    if len(filmed):  # the first successful episode of the protocol's video part count, filmed again from the side
        shown = filmed.iloc[0]
        text += ["", f"The video (`robot_episode.mp4` and its strip, below): seed {shown.seed}, scene "
                     f"{int(shown.video_scene)} with {amount(runs, 'protocol.video_objects', 'parts')}, the first "
                     "delivered episode of that count, with each iteration's decision as the caption."]
        artifacts = {name: (shown.run_id, f"videos/{name}")
                     for name in ("robot_episode.mp4", "robot_episode_strip.jpg")}
    return Section("Table 6.2 (robot row): Algorithm 4 with the robot", "\n".join(text), pd.DataFrame(records), {},
                   artifacts)


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch6_robot",
    title="Ch.6 iterative grasping with the robot (Algorithm 4 in a robosuite clutter cell)",
    note="Table 6.2's rendered scenes in a robosuite cell with a simulated UR5e and a Robotiq 2F-140, not the "
         "thesis' UR10 with a 2F-85 at real parts; the camera is the scenes' own, rendered with depth.",
    studies=(Study("ch6/table_6_2_robot"),),
)
