"""Report section of the Ch.5 HRC loop with the robot (thesis 5.2.3, Figs. 5.8-5.10): Table 5.2 extended with the
robot's placements in the assembly cell and the sessions that end with the goal assembled."""

from __future__ import annotations

import pandas as pd

from hrc_lab.report.plan import Plan, Study
from hrc_lab.report.runs import amount, over_seeds, run_tables, setting, spread
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, markdown_table, thesis_cells, thesis_fmt, thesis_results

CELLS = ["1goal", "2goals", "3goals"]


def per_cell(runs: pd.DataFrame, suffix: str, with_thesis: bool) -> tuple[list[dict], list[dict]]:
    """One row per goal count: AD / SG / SC (thesis in brackets for normal sessions), the robot's commands,
    refusals, placement success and the completed assemblies; ``suffix`` "" (normal) or "_fast"."""
    thesis = thesis_results()["ch5"]["table_5_2"]
    rows, records = [], []
    for cell in thesis_cells(runs.cell, CELLS):
        part = runs[runs.cell == cell]
        goals = int(cell.split("goal")[0])  # "1goal", "3goals", a user's "10goals"
        ref = thesis.get(f"goals_{goals}", [(None, None)] * 3)  # the thesis' AD, SG, SC; None: a count not run
        sessions = int(part.n_fast_sessions.sum() if suffix else part.n_sessions.sum())
        row = {"goals": goals, "seeds": len(part), "sessions": sessions}
        for k, (metric, title) in enumerate((("ad_acc", "AD %"), ("sg_acc", "SG %"), ("sc_acc", "SC %"))):
            mean, std = (100 * v for v in spread(part, metric + suffix))
            row[title] = fmt(mean, std, 1) + (f" ({thesis_fmt(*ref[k], 1)})" if with_thesis else "")
            records.append({"goals": goals, "sessions": suffix or "normal", "metric": metric, "mean": mean,
                            "std": std})
        row["robot commands"] = int(part.get(f"robot_commands{suffix}", pd.Series(dtype=float)).sum())
        for metric, title in (("robot_refused_rate", "refused %"), ("robot_placement_sr", "placed %"),
                              ("complete_rate", "assembled %")):
            mean, std = (100 * v for v in spread(part, metric + suffix))
            row[title] = fmt(mean, std, 1)
            records.append({"goals": goals, "sessions": suffix or "normal", "metric": metric, "mean": mean,
                            "std": std})
        if recovering(runs):
            mean, std = spread(part, "recoveries_per_session" + suffix)
            row["recoveries / session"] = fmt(mean, std, 2)
            records.append({"goals": goals, "sessions": suffix or "normal", "metric": "recoveries_per_session",
                            "mean": mean, "std": std})
        rows.append(row)
    return rows, records


def recovering(runs: pd.DataFrame) -> bool:
    """Whether the runs' loop recovered from contradicting placements (``protocol.recovery``, hrc_lab's)."""
    return setting(runs, "protocol.recovery") == "True"


def recovery_text(sessions: pd.DataFrame) -> str:
    """What the recovery did: how many fixes, in how many sessions, and how those sessions ended."""
    if "recoveries" not in sessions or not len(sessions):
        return ""
    fixed = sessions[sessions.recoveries > 0]
    return (f"**Recovery** (`protocol.recovery=true`, hrc_lab's, beyond Algorithm 3): after every plan, a recorded "
            "part the inferred goal does not want on its position (or a second part recorded on a position) is "
            "named, the robot takes the part there back to its bin and places the goal's part, and the loop plans "
            "again; only a goal that agrees with most recorded pairs is trusted to fix the others, and each position "
            "is fixed at most once per session. A worker's placement recorded on a position that "
            "already holds that part type (one of the two was read on the wrong position) is re-read as the nearest "
            "free position where the inferred goal wants it. Here "
            f"{int(sessions.recoveries.sum())} recoveries in {len(fixed)} of {len(sessions)} sessions "
            f"({int(fixed.recovered.sum())} carried out); {int(fixed.complete.sum())} of those {len(fixed)} sessions "
            "ended assembled.")


@register_section("hrc_session")
def hrc_session(runs: pd.DataFrame) -> Section:
    normal, records = per_cell(runs, "", with_thesis=True)
    fast, fast_records = per_cell(runs, "_fast", with_thesis=False) if runs.n_fast_sessions.sum() else ([], [])
    help_table = run_tables(runs, "robot_help")
    sessions = run_tables(runs, "hrc_sessions")
    right = (sessions.sg_acc.fillna(1) == 1) & (sessions.sc_acc.fillna(1) == 1)  # NaN: the session had no such step
    cause = (f"Of the {int(right.sum())} sessions whose Semantic Guidance and Semantic Control were right at every "
             f"step, {int(sessions.complete[right].sum())} ended with the goal assembled; of the {int((~right).sum())} "
             f"with a planner or detection error, {int(sessions.complete[~right].sum())} did. A wrong command or a "
             "mis-detected human placement puts a part where the goal wants another, and the position is then "
             "taken when the right part comes (the table below)." if len(sessions) else "")
    reasons = (help_table.reason.str.replace(r"p\d", "p<k>", regex=True).str.replace(r"\d+\.\d cm", "<x> cm",
                                                                                     regex=True)
               .str.replace(r"(robot|human) o\d->p<k>", r"\1 o<i>->p<k>", regex=True).value_counts()
               if len(help_table) else pd.Series(dtype=int))
    detection = thesis_results()["ch5"]["text"]["detection_latency_ms"]
    text = [
        "Table 5.2's generated sessions streamed through MediaPipe tracking, the action detector (`hand_lstm_fcn`) "
        "and the semantic planner (Algorithm 3), with the robot cell built from the same env spec "
        "(`hrc_lab/env/robot/assembly_cell.py`: UR5e, suction cup, part bins, bracket p1..p6). Every human "
        "placement the loop records puts the part on the bracket (no human model); every Semantic Control "
        "command runs PickandPlace(o, p) with the scripted expert. `refused`: commands the robot could not carry "
        "out (no part of that type left, position taken, pair not allowed by Table 5.1), so it asked for help; "
        "`placed`: commands it executed whose part rests within "
        f"{amount(runs, 'env.robot.place_tolerance', 'm')} of the position with no collision; `assembled`: "
        "sessions whose bracket holds exactly the goal at the end. AD / SG / SC as in Table 5.2, on the "
        f"first {amount(runs, 'protocol.sessions', 'normal sessions')} of `ch5/table_5_2`'s of the same seed "
        "(AD depends on the detector only; SG and SC can differ where "
        "the cell refused a step, which the planner then never sees); thesis (20 real experiments x 5) in brackets; "
        f"{over_seeds(runs)}. The video is generated in advance, so it shows the "
        "expert's part appearing after each screw whatever the robot did; the cell is what the robot really did.",
        "",
        "Normal sessions:",
        "",
        markdown_table(pd.DataFrame(normal)),
        "",
        "Fast sessions (every action about twice as fast, motion-blurred; the thesis' stated failure case):",
        "",
        markdown_table(pd.DataFrame(fast)) if fast else "(none in these runs)",
        "",
        cause,
        "",
        recovery_text(sessions) if recovering(runs) else "",
        "",
        "Placements the cell refused or that failed (all sessions; `robot`: a command the robot could not carry "
        "out, so it asked for help; `human`: a placement the loop recorded that the cell could not hold, e.g. a "
        "position a wrong earlier step had filled; part types and positions generalised):",
        "",
        (reasons.rename_axis("reason").reset_index(name="count").to_markdown(index=False) if len(reasons)
         else "(never)"),
        "",
        f"Latency on this CPU: from the start of the frame that closed a screw window (its tracking included) to "
        f"the robot's first motion command {fmt(*spread(runs, 'screw_latency_ms'), 1)} ms (median per run; thesis: "
        f"detection in {detection} ms); detector {fmt(*spread(runs, 'classify_ms'), 1)} ms per window; "
        f"MediaPipe {fmt(*spread(runs, 'tracking_ms_per_frame'), 1)} ms per frame. One PickandPlace takes "
        f"{fmt(*spread(runs, 'pick_place_sim_s'), 2)} s of simulated time "
        f"({fmt(*spread(runs, 'pick_place_wall_s'), 2)} s of wall clock).",
    ]
    # the video: the filmed session (protocol.video_session; older runs filmed session 0) of the first run (by goal
    # count, seed) whose filmed session ended assembled, with a recovery in it when the loop recovered
    filmed = dict(zip(runs.run_id, runs.get("filmed_session", pd.Series(0.0, index=runs.index)).fillna(0)))
    wanted = sessions[sessions.session == sessions.run_id.map(filmed)] if len(sessions) else sessions
    good = wanted[wanted.complete.astype(bool) & ((wanted.recoveries > 0) if recovering(runs) else True)]
    shown_ok = set(good.run_id)
    ordered = runs.sort_values(["cell", "seed"])
    shown = next((r for r in ordered.itertuples() if r.run_id in shown_ok), next(ordered.itertuples()))
    what = "with a recovery, " if recovering(runs) else ""
    outcome = f"{what}it ends assembled" if shown.run_id in shown_ok else f"no filmed session ended {what}assembled"
    log = ""
    if recovering(runs) and len(wanted):
        lines = wanted.recovery_log[wanted.run_id == shown.run_id].fillna("")
        log = f" The loop said: \"{lines.iloc[0]}\"." if len(lines) and lines.iloc[0] else ""
    text.append(f"The video (linked below): session {int(filmed[shown.run_id])} of "
                f"`{shown.cell}`, seed {shown.seed} ({outcome}); the worker's view with what the system saw and said, "
                f"beside the robot cell with its last command.{log}")
    artifacts = {"hrc_session.mp4": (shown.run_id, "videos/session_side_by_side.mp4")}
    return Section("The HRC loop with the robot: Table 5.2 extended", "\n".join(text),
                   pd.DataFrame(records + fast_records), {}, artifacts)


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch5_hrc",
    title="Ch.5 human-robot collaboration with the robot in the loop (Algorithm 3's PickandPlace)",
    note="The worker is a generated video, not a person on a RealSense camera; the robot is a simulated UR5e "
         "with a suction cup in robosuite, not the thesis' UR10 at a real bench.",
    studies=(Study("ch5/hrc_session"),),
)
