"""Report section of the Ch.5 HRC loop with the robot (thesis 5.2.3, Figs. 5.8-5.10): Table 5.2 extended with the
robot's placements in the assembly cell and the sessions that end with the goal assembled."""

from __future__ import annotations

import pandas as pd

from hrc_lab.report.ch5_perception import TABLE_5_2_METRICS
from hrc_lab.report.ch5_planner import table_5_2_rows
from hrc_lab.report.headline import results_frame
from hrc_lab.report.plan import Plan, Study
from hrc_lab.report.runs import amount, over_seeds, run_tables, setting, spread
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, markdown_table, thesis_cells

CELLS = ["1goal", "2goals", "3goals"]
# the section's columns (percent): Table 5.2's, then the robot's; per normal and fast sessions (suffix "_fast")
SHOWN = {"ad_acc": "AD %", "sg_acc": "SG %", "sc_acc": "SC %", "robot_refused_rate": "refused %",
         "robot_placement_sr": "placed %", "complete_rate": "assembled %"}
LATENCIES = ("screw_latency_ms", "classify_ms", "tracking_ms_per_frame", "pick_place_sim_s", "pick_place_wall_s")


def recovering(runs: pd.DataFrame) -> bool:
    """Whether the runs' loop recovered from contradicting placements (``protocol.recovery``, hrc_lab's)."""
    return setting(runs, "protocol.recovery") == "True"


def per_cell(runs: pd.DataFrame) -> tuple[list[dict], list[dict], list[dict]]:
    """The table's rows (normal sessions), Table 5.2's results (AD / SG / SC in percent, per goal cell) and the CSV's
    records (normal and fast sessions: every metric, the robot's commands and recoveries, the latencies)."""
    rows, results, csv = [], [], []
    for cell in thesis_cells(runs.cell, CELLS):
        part = runs[runs.cell == cell]
        row = {"goals": int(cell.split("goal")[0])}  # "1goal", "3goals", a user's "10goals"
        for sessions, suffix in (("normal", ""), ("fast", "_fast")):
            metrics = [*SHOWN, "robot_commands", "recoveries_per_session"]
            for metric in metrics:
                values = spread(part, metric + suffix)
                mean, std = (100 * v for v in values) if metric in SHOWN else values
                csv.append({"cell": cell, "sessions": sessions, "metric": metric, "mean": mean, "std": std})
                if suffix:
                    continue
                if metric in SHOWN or (metric == "recoveries_per_session" and recovering(runs)):
                    row[SHOWN.get(metric, "recoveries / session")] = fmt(mean, std, 1 if metric in SHOWN else 2)
                if metric in TABLE_5_2_METRICS:
                    results.append({"row": cell, "column": TABLE_5_2_METRICS[metric], "mean": mean, "std": std,
                                    "n": int(part[metric].notna().sum())})
        csv += [{"cell": cell, "sessions": "all", "metric": metric, "mean": mean, "std": std}
                for metric in LATENCIES for mean, std in [spread(part, metric)]]
        rows.append(row)
    return rows, results, csv


def session_records(sessions: pd.DataFrame, help_table: pd.DataFrame) -> list[dict]:
    """What decides an assembly, for the CSV: the sessions right at every step (Semantic Guidance and Control) and
    those with an error, how many of each ended assembled, the recoveries, and every reason the robot asked for help
    (part types and positions generalised)."""
    if not len(sessions):
        return []
    right = (sessions.sg_acc.fillna(1) == 1) & (sessions.sc_acc.fillna(1) == 1)  # NaN: the session had no such step
    counts = {"sessions_right": right.sum(), "assembled_of_right": sessions.complete[right].sum(),
              "sessions_with_error": (~right).sum(), "assembled_of_with_error": sessions.complete[~right].sum()}
    if "recoveries" in sessions:
        fixed = sessions[sessions.recoveries > 0]
        counts |= {"recoveries": sessions.recoveries.sum(), "sessions_recovering": len(fixed),
                   "assembled_of_recovering": fixed.complete.sum()}
    reasons = (help_table.reason.str.replace(r"p\d", "p<k>", regex=True)
               .str.replace(r"\d+\.\d cm", "<x> cm", regex=True)
               .str.replace(r"(robot|human) o\d->p<k>", r"\1 o<i>->p<k>", regex=True).value_counts()
               if len(help_table) else pd.Series(dtype=int))
    counts |= {f"help: {reason}": count for reason, count in reasons.items()}
    return [{"cell": "all", "sessions": "all", "metric": metric, "mean": float(count), "std": float("nan")}
            for metric, count in counts.items()]


def filmed(runs: pd.DataFrame, sessions: pd.DataFrame) -> tuple[object, str]:
    """The run whose video the section links and what it shows: the filmed session (``protocol.video_session``;
    older runs filmed session 0) of the first run (by goal count, seed) whose filmed session ended assembled, with
    a recovery in it when the loop recovered."""
    session_of = dict(zip(runs.run_id, runs.get("filmed_session", pd.Series(0.0, index=runs.index)).fillna(0)))
    wanted = sessions[sessions.session == sessions.run_id.map(session_of)] if len(sessions) else sessions
    good = set(wanted[wanted.complete.astype(bool) & ((wanted.recoveries > 0) if recovering(runs) else True)].run_id)
    ordered = runs.sort_values(["cell", "seed"])
    shown = next((r for r in ordered.itertuples() if r.run_id in good), next(ordered.itertuples()))
    what = "with a recovery, " if recovering(runs) else ""
    outcome = f"{what}it ends assembled" if shown.run_id in good else f"no filmed session ended {what}assembled"
    return shown, f"session {int(session_of[shown.run_id])} of `{shown.cell}`, seed {shown.seed} ({outcome})"


@register_section("hrc_session")
def hrc_session(runs: pd.DataFrame) -> Section:
    rows, results, csv = per_cell(runs)
    sessions = run_tables(runs, "hrc_sessions")
    csv += session_records(sessions, run_tables(runs, "robot_help"))
    shown, video = filmed(runs, sessions)
    recovery = (" ★ Recovery (hrc_lab's, beyond Algorithm 3): the robot takes back a recorded part the inferred goal "
                "does not want on its position and places the goal's part." if recovering(runs) else "")
    text = [
        f"Table 5.2's first {amount(runs, 'protocol.sessions', 'sessions')} per seed through MediaPipe, the detector "
        "and Algorithm 3, a UR5e running each Semantic Control command as PickandPlace(o, p) in the robot cell. "
        "Refused: commands it could not carry out; placed: executed ones whose part rests within "
        f"{amount(runs, 'env.robot.place_tolerance', 'm')}; assembled: sessions ending with the goal; "
        f"{over_seeds(runs)}.{recovery} Video: {video}.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    artifacts = {"hrc_session.mp4": (shown.run_id, "videos/session_side_by_side.mp4")}
    return Section("The HRC loop with the robot: Table 5.2 extended", "\n".join(text), pd.DataFrame(csv), {},
                   artifacts, results=results_frame(results))


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch5_hrc",
    title="Ch.5 human-robot collaboration with the robot in the loop (Algorithm 3's PickandPlace)",
    note="The worker is a generated video, not a person on a RealSense camera; the robot is a simulated UR5e "
         "with a suction cup in robosuite, not the thesis' UR10 at a real bench.",
    studies=(
        Study("ch5/hrc_session"),
        Study("ch5/hrc_session", ("protocol.recovery=True",), key="recovery", star=True,
              title="★ The HRC loop with the robot and hrc_lab's recovery from contradicting placements"),
    ),
    rows=table_5_2_rows("Table 5.2 with the robot in the loop", "hrc_session",
                        {1: "our detector on windows of generated sessions",
                         3: "a wrong step stays on the bracket for the steps after it ([★ recovery](#recovery)); "
                            "few sessions per seed"},
                        star="recovery", star_label="recovery"),
)
