"""Report sections of the Ch.5 semantic-planner experiments: Fig. 5.7 and the planner columns of Table 5.2."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from hrc_lab.report.headline import results_frame  # noqa: E402
from hrc_lab.report.plan import Pick, Plan, Row, Study  # noqa: E402
from hrc_lab.report.runs import amount, mean_std, over_seeds, spread  # noqa: E402
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, markdown_table, thesis_cells, thesis_results  # noqa: E402

CELLS = ["1goal", "2goals", "3goals"]
PLANNER = "semantic_planner"  # the results' row of the planner
# Table 5.2's columns (thesis_results.yaml ch5.table_5_2.columns) and the metrics that are ours of them
SG, SC = "semantic_guidance", "semantic_control"


def _cells(runs: pd.DataFrame) -> list[str]:
    return thesis_cells(runs.cell, CELLS)


def goal_cell(goals: int) -> str:
    """The cell of ``goals`` goal configurations in play (``AssembleToOrderSpec.cell``): "1goal", "3goals"."""
    return f"{goals}goal" + ("s" if goals > 1 else "")


def _training_sets(runs: pd.DataFrame) -> dict[str, str]:
    """Metric -> row label of Fig. 5.7's table: each training ratio (``sr_lam<r>``), then each absolute training-set
    size (``sr_n<k>``, ``protocol.train_counts``), in order."""
    ratios = sorted((float(c[len("sr_lam"):]), c) for c in runs.columns if c.startswith("sr_lam"))
    counts = sorted((int(c[len("sr_n"):]), c) for c in runs.columns if c.startswith("sr_n")
                    and c[len("sr_n"):].isdigit())
    return {**{column: f"λ={ratio:g}" for ratio, column in ratios},
            **{column: f"{count} scenarios" for count, column in counts}}


@register_section("fig_5_7")
def fig_5_7(runs: pd.DataFrame) -> Section:
    ref = thesis_results()["ch5"]["text"]
    trained, total = ref["planner_trained_of_scenarios_three_goals"]
    cells, labels = _cells(runs), _training_sets(runs)
    records = []
    for column, label in labels.items():
        for _, r in mean_std(runs, ["cell"], column).iterrows():
            records.append({"cell": r.cell, "train": label, "sr_mean": r["mean"], "sr_std": r["std"], "seeds": r.n})
    for _, r in mean_std(runs, ["cell"], "sr_ceiling").iterrows():
        records.append({"cell": r.cell, "train": "best possible", "sr_mean": r["mean"], "sr_std": float("nan"),
                        "seeds": r.n})
    frame = pd.DataFrame(records)
    table = frame.assign(value=[fmt(m, s) for m, s in zip(frame.sr_mean, frame.sr_std)])
    table = table.pivot(index="train", columns="cell", values="value")
    table = table.reindex(index=[*labels.values(), "best possible"], columns=cells).fillna("–")
    scenarios = runs.groupby("cell")["n_scenarios"].first().reindex(cells)
    text = [
        f"Success rate (goal, next object and every part type's plan right) of the planner trained "
        f"({amount(runs, 'reasoning.steps', 'steps')}) on a random fraction λ, or a number, of the scenarios (every "
        f"partially assembled state of every goal: {', '.join(f'{int(n)} at {c}' for c, n in scenarios.items())}) "
        f"and scored on all; {over_seeds(runs)}. Best possible: one of each group of scenarios identical under two "
        "goals (`ambiguous_scenarios.md`).",
        "",
        markdown_table(table.rename_axis("trained on").reset_index()),
    ]
    results = []
    point = runs[runs.n_scenarios == total]  # the thesis' point: trained on 143 of the 186 scenarios (3 goals)
    if f"sr_n{trained}" in point and point[f"sr_n{trained}"].notna().any():
        mean, std = spread(point, f"sr_n{trained}")
        results.append({"row": PLANNER, "column": "", "mean": mean, "std": std,
                        "n": int(point[f"sr_n{trained}"].notna().sum())})
    most_goals = runs[runs.cell == cells[-1]].iloc[0].run_id
    artifacts = {"ambiguous_scenarios.md": (most_goals, "tables/ambiguous_scenarios.md")}
    figure = _plot(frame, cells, trained / total, ref["planner_sr_143_of_186_three_goals"])
    return Section("Fig. 5.7: semantic planner over the training ratio", "\n".join(text), frame,
                   {"fig_5_7.png": figure}, artifacts, results=results_frame(results))


def _plot(frame: pd.DataFrame, cells: list[str], ratio: float, thesis: float):
    """Fig. 5.7: our success rate over the training ratio per goal count, and the thesis' point (``ratio``,
    ``thesis``)."""
    fig, ax = plt.subplots(figsize=(6, 3.8))
    curve = frame[frame.train.str.startswith("λ=")].assign(ratio=lambda f: f.train.str[2:].astype(float))
    for cell in cells:
        part = curve[curve.cell == cell].sort_values("ratio")
        ax.errorbar(part.ratio, part.sr_mean, yerr=part.sr_std, marker="o", capsize=2, label=cell)
    ax.scatter([ratio], [thesis], marker="*", s=160, color="black", zorder=4, label="thesis (3 goals)")
    ax.set_xlabel("training ratio λ")
    ax.set_ylabel("success rate")
    ax.set_ylim(-0.03, 1.05)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


@register_section("table_5_2_planner")
def table_5_2_planner(runs: pd.DataFrame) -> Section:
    ref_ms = thesis_results()["ch5"]["text"]["planning_latency_ms_gpu"]
    rows, records, csv = [], [], []
    for cell in _cells(runs):
        part = runs[runs.cell == cell]
        row = {"goals": cell.split("goal")[0]}  # "1goal", "3goals", a user's "10goals"
        for metric, column, title in (("sg_acc", SG, "SG %"), ("sc_acc", SC, "SC %")):
            mean, std = (100 * v for v in spread(part, metric))
            row[title] = fmt(mean, std, 1)
            records.append({"row": cell, "column": column, "mean": mean, "std": std,
                            "n": int(part[metric].notna().sum())})
        events = part.n_assembly_events.mean(), part.n_screw_events.mean()
        row["assembly / screw events per seed"] = f"{events[0]:.0f} / {events[1]:.0f}"
        row["ms per decision (CPU)"] = fmt(part.latency_ms.median())
        rows.append(row)
        csv.append({"cell": cell, "seeds": len(part), "sg_mean": records[-2]["mean"], "sg_std": records[-2]["std"],
                    "sc_mean": records[-1]["mean"], "sc_std": records[-1]["std"], "assembly_events": events[0],
                    "screw_events": events[1], "latency_ms": part.latency_ms.median()})
    text = [
        f"Table 5.2's SG and SC with perfect action labels (the planner alone; the thesis' include its detector's "
        f"errors): {amount(runs, 'protocol.sessions', 'generated sessions')} per goal count and seed (random goal "
        f"and human order; a screw hands the next part to the robot) through the Algorithm 3 loop; "
        f"{over_seeds(runs)}. Latency: median, graph and decoding included (thesis: {ref_ms} ms on a GPU).",
        "",
        pd.DataFrame(rows).to_markdown(index=False, disable_numparse=True),
    ]
    return Section("Table 5.2 (planner columns): Semantic Guidance and Control", "\n".join(text), pd.DataFrame(csv),
                   results=results_frame(records))


def table_5_2_rows(table: str, study: str, why: dict[int, str], columns: tuple[str, ...] = (),
                   star: str | None = None, star_label: str = "", headline: bool = True) -> tuple[Row, ...]:
    """The rows of Table 5.2 (one per goal count the thesis ran) as ``study``'s results give them (their rows are the
    goal cells), with hrc_lab's ★ method from the study ``star``; ``why`` per goal count."""
    counts = sorted(int(key.split("_")[1]) for key in thesis_results()["ch5"]["table_5_2"] if key.startswith("goals_"))
    return tuple(Row(table, f"{goals} goal{'s' if goals > 1 else ''}", f"ch5.table_5_2.goals_{goals}",
                     Pick(study, goal_cell(goals)), star=Pick(star, goal_cell(goals), star_label) if star else None,
                     columns=columns, why=why.get(goals, ""), headline=headline) for goals in counts)


TRAINED, SCENARIOS = thesis_results()["ch5"]["text"]["planner_trained_of_scenarios_three_goals"]

# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch5_planner",
    title="Ch.5 graph semantic planner: goal inference, next object and text plans",
    note="Our scenarios come from the assemble-to-order domain (`hrc_lab/env/assembly/spec.py`) with our own "
         "three goal configurations (the thesis' Fig. 5.4 is not legible in its text).",
    studies=(Study("ch5/fig_5_7"), Study("ch5/table_5_2_planner")),
    rows=(
        Row("Fig. 5.7", f"Trained on {TRAINED} of {SCENARIOS} scenarios (3 goals)",
            "ch5.text.planner_sr_143_of_186_three_goals", Pick("fig_5_7", PLANNER),
            why="our own three goals, which share pairs as the thesis' do"),
        *table_5_2_rows("Table 5.2 (planner columns, perfect action labels)", "table_5_2_planner",
                        {1: "perfect action labels: the planner without a detector's errors"}, columns=(SG, SC),
                        headline=False),
    ),
)
