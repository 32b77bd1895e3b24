"""The test conditions of Sec. 4.4.3 beside the position ranges a Ch.4 run covered: one paragraph, shared by the
Table 4.1 (reasoning) and Table 4.2 (motion) sections."""

from __future__ import annotations

import pandas as pd

from hrc_lab.report.runs import keyed, setting
from hrc_lab.report.thesis import thesis_results

NARROWER = 0.8  # goal positions spanning less than this share of Sec. 4.4.3's, in x or y, make a narrower test


def conditions_paragraph(runs: pd.DataFrame, goals: str) -> list[str]:
    """Sec. 4.4.3's ranges beside the ones these runs covered (largest over cells and seeds; runs log
    ``pick_span_*``, ``goal_span_*``, ``object_goal_*``), then ``goals``: why goal positions vary as they do."""
    runs = runs.dropna(subset=["pick_span_x_m"]) if "pick_span_x_m" in runs else runs.iloc[:0]
    if runs.empty:  # runs older than the spans
        return []
    ref = thesis_results()["ch4"]["text"]
    span = runs[["pick_span_x_m", "pick_span_y_m", "goal_span_x_m", "goal_span_y_m"]].max()
    low, high = runs["object_goal_min_m"].min(), runs["object_goal_max_m"].max()
    pick, goal, dist = ref["position_variation_pick_m"], ref["position_variation_goal_m"], ref["object_goal_distance_m"]
    narrower = span.goal_span_x_m < NARROWER * goal["x"] or span.goal_span_y_m < NARROWER * goal["y"]
    return [
        "",
        *(["**Not comparable with sections run at Sec. 4.4.3's ranges**: these runs' goal positions span less than "
           f"{NARROWER:.0%} of the thesis' in x or y (below), a narrower test than the default section's.", ""]
          if narrower else []),
        f"Test conditions (Sec. 4.4.3's ranges in brackets): picking positions span {span.pick_span_x_m:.2f} m in x "
        f"and {span.pick_span_y_m:.2f} m in y ({pick['x']} × {pick['y']}); goal positions {span.goal_span_x_m:.2f} × "
        f"{span.goal_span_y_m:.2f} m ({goal['x']} × {goal['y']}); object-goal distances {low:.2f}–{high:.2f} m "
        f"({dist[0]}–{dist[1]}). The picking span is the pending area's, one cell of "
        f"{keyed(runs, 'env.pending_spacing', 'm')} per product (fewer products, a shorter area); goal positions "
        f"vary with the box (box jitter ± {setting(runs, 'env.box_jitter.0')} × ± {setting(runs, 'env.box_jitter.1')} "
        f"m, `env.box_jitter`): {goals}",
    ]
