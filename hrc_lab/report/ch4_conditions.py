"""The test conditions of Sec. 4.4.3 beside the position ranges a Ch.4 run covered: one clause, shared by the
Table 4.1 (reasoning) and Table 4.2 (motion) captions."""

from __future__ import annotations

import pandas as pd

from hrc_lab.report.thesis import thesis_results

SPANS = ("pick_span_x_m", "pick_span_y_m", "goal_span_x_m", "goal_span_y_m")  # logged by every run of both tables


def position_spans(runs: pd.DataFrame) -> str:
    """ "positions span picking 0.35 × 0.15 m, goals 0.43 × 0.28 m (Sec. 4.4.3: 0.3 × 0.15, 0.35 × 0.2)": the
    largest spans over the runs' cells and seeds (the goals' follow the box, ``env.box_jitter``); "" for runs that
    did not log them."""
    logged = runs.dropna(subset=list(SPANS)) if set(SPANS) <= set(runs) else runs.iloc[:0]
    if logged.empty:
        return ""
    span = logged[list(SPANS)].max()
    ref = thesis_results()["ch4"]["text"]
    pick, goal = ref["position_variation_pick_m"], ref["position_variation_goal_m"]
    return (f"positions span picking {span.pick_span_x_m:.2f} × {span.pick_span_y_m:.2f} m, goals "
            f"{span.goal_span_x_m:.2f} × {span.goal_span_y_m:.2f} m (Sec. 4.4.3: {pick['x']} × {pick['y']}, "
            f"{goal['x']} × {goal['y']})")
