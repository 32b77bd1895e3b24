"""Report sections of the Ch.4 reasoning experiments: Table 4.1, Fig. 4.7, the practical scenarios (Sec. 4.4.5,
Fig. 4.17), Fig. 4.9; and the report's plan."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from hrc_lab.reasoning.configs import CH4, DEFAULT_POSITION_FRAME, POSITION_FRAMES, REASONERS  # noqa: E402
from hrc_lab.report.ch4_conditions import position_spans  # noqa: E402
from hrc_lab.report.headline import from_stats, results_frame, within  # noqa: E402
from hrc_lab.report.plan import Pick, Plan, Row, Study  # noqa: E402
from hrc_lab.report.plots import success_bars  # noqa: E402
from hrc_lab.report.runs import NOT_LOGGED, amount, mean_std, over_seeds, setting, spread  # noqa: E402
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import (  # noqa: E402
    fmt,
    markdown_table,
    one_seed,
    thesis_cells,
    thesis_fmt,
    thesis_results,
    thesis_value,
)

CELLS = ["2of3", "3of3", "3of5", "4of5"]
# The methods' rows (in the order they are registered), display names and variants: their registration in
# hrc_lab/reasoning/configs.py
METHODS = list(REASONERS.family(CH4))
LABELS = REASONERS.labels(CH4)
OURS_FAMILY = list(REASONERS.with_variants("ours"))  # the thesis' module and issue 24's variants of it
# per-head, per-stage accuracies and where wrong picks point (every evaluation logs them; the sections' CSVs)
HEADS = {"acc_o_pick": "P_o pick", "acc_o_place": "P_o place", "acc_g_pick": "P_g pick", "acc_g_place": "P_g place"}
PICK_ERRORS = {"pick_error_area": "the packaging area", "pick_error_packed": "packed products",
               "pick_error_unselected": "unselected products", "pick_error_other": "other selected products"}
DIAGNOSTICS = (*HEADS, *PICK_ERRORS)
TABLE_4_1_EXTRA = ("train_acc_o", "train_acc_g", "latency_ms_batch1", "latency_ms_batched")
BELOW = 0.95  # a point where ours scores below this is one where it "fails" (the diagnostics' sentence)


def _frame_text(frame: str) -> str:
    """How positions entered the runs' encodings, in words, from :data:`POSITION_FRAMES`."""
    if frame not in POSITION_FRAMES:
        return frame  # runs that differ ("table_dm or world_m")
    origin, scale = POSITION_FRAMES[frame]
    where = "relative to the table top's centre" if origin == "table" else "in the world frame"
    return f"{where}, in {'decimetres' if scale == 10 else 'metres' if scale == 1 else f'metres x {scale:g}'}"


def _means(part: pd.DataFrame, metrics, pattern: str = "{}") -> dict[str, float]:
    """Mean over ``part``'s runs of each logged metric ``pattern.format(metric)``, keyed by ``metric``."""
    return {m: float(part[pattern.format(m)].mean()) for m in metrics if pattern.format(m) in part}


@register_section("table_4_1")
def table_4_1(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch4"]["table_4_1"]
    stats = mean_std(runs, ["method", "cell"], "sr")
    cells = thesis_cells(stats["cell"], CELLS)
    methods = thesis_cells(stats["method"], METHODS)
    rows, csv = [], []
    for method in methods:
        row = {"method": LABELS.get(method, method)}
        for cell in cells:
            part = runs[(runs.method == method) & (runs.cell == cell)]
            mean, std = spread(part, "sr")
            ref = thesis_value(thesis.get(method), thesis["columns"], cell)  # None: a method or cell not run
            row[cell] = f"{fmt(mean, std)} ({thesis_fmt(ref[0]) if ref else '–'})"
            csv.append({"method": method, "cell": cell, "sr_mean": mean, "sr_std": std,
                        "seeds": int(part.sr.notna().sum()), "thesis_mean": ref[0] if ref else None,
                        "thesis_std": ref[1] if ref else None,
                        **_means(part, (*DIAGNOSTICS, *TABLE_4_1_EXTRA))})
        rows.append(row)
    frame = setting(runs, "reasoning.position_frame")
    frame = DEFAULT_POSITION_FRAME if frame == NOT_LOGGED else frame  # runs from before the key had the default
    text = (f"CASE 1 success rate (all 2n predictions of a trial right) after {setting(runs, 'reasoning.steps')} "
            f"training steps (`reasoning.steps`), positions {_frame_text(frame)} (`reasoning.position_frame`); seed "
            f"k tests fold k of {setting(runs, 'protocol.n_folds')}; {over_seeds(runs)}; thesis in brackets.")
    spans = position_spans(runs)
    text += f" {spans[0].upper()}{spans[1:]}." if spans else ""
    ours = runs[runs.method == "ours"]
    if "latency_ms_batch1" in ours and ours.latency_ms_batch1.notna().any():
        text += (f" Ours decides in {ours.latency_ms_batch1.median():.1f} ms at batch 1 (thesis "
                 f"{thesis_results()['ch4']['text']['reasoning_latency_ms']} ms).")
    table = pd.DataFrame(csv)
    figure = success_bars(table, cells, methods, LABELS, "Table 4.1", thesis_col="thesis_mean")
    return Section("Table 4.1: reasoning success rates", f"{text}\n\n{markdown_table(pd.DataFrame(rows))}", table,
                   {"table_4_1.png": figure}, results=results_frame(from_stats(stats)))


# ---- Fig. 4.7 ------------------------------------------------------------------------------------------------

FULL = 1.0  # λ = 1: trained on every goal configuration (the thesis' CASE 2 statement)


def point_row(method: str, case: str, ratio: float) -> str:
    """The results' row of ``method`` at (``case``, λ = ``ratio``) of Fig. 4.7, e.g. "ours case1 λ=0.6" (its
    column: the cell)."""
    return f"{method} {case} λ={ratio:g}"


def configurations(cell: str) -> int:
    """Goal configurations of an "<n>of<m>" cell: mCn selections times n! slot assignments (Fig. 4.6)."""
    n, m = (int(k) for k in cell.split("of"))
    return math.comb(m, n) * math.factorial(n)


def stated_points() -> list[tuple[str, str, float]]:
    """(case, cell, λ) of each of the thesis' stated Fig. 4.7 points (Sec. 4.4.1): CASE 1 at its stated λ in its
    cell, CASE 1 in 4of5 with the stated number of configurations unseen, CASE 2 at λ = 1 in each stated cell."""
    thesis = thesis_results()["ch4"]["figure_4_7"]
    unseen = thesis["case1_4of5_unseen_configs_handled"] / configurations("4of5")
    return [*(("case1", cell, thesis["case1_ours_unseen_lambda"]) for cell in thesis["case1_ours_unseen_sr"]),
            ("case1", "4of5", round(1 - unseen, 6)),
            *(("case2", cell, FULL) for cell in thesis["case2_ours_sr_at_lambda_1"])]


def _lambda_columns(runs: pd.DataFrame, case: str) -> dict[float, str]:
    prefix = f"{case}_sr_lam"
    return {float(c[len(prefix):]): c for c in runs.columns if c.startswith(prefix)}


def _curves(runs: pd.DataFrame) -> pd.DataFrame:
    """Every (case, λ, method, cell) of Fig. 4.7: success rate mean, std and seeds, and the mean of every head
    accuracy, pick error and training-set size the runs logged."""
    records = []
    for case in ("case1", "case2"):
        for ratio, column in sorted(_lambda_columns(runs, case).items()):
            logged = column.split("_lam", 1)[1]  # the ratio as the run logged it
            pattern = f"{case}_{{}}_lam{logged}"
            for (method, cell), part in runs.groupby(["method", "cell"]):
                mean, std = spread(part, column)
                records.append({"case": case, "ratio": ratio, "method": method, "cell": cell, "sr_mean": mean,
                                "sr_std": std, "seeds": int(part[column].notna().sum()),
                                **_means(part, (*DIAGNOSTICS, "n_train_demos"), pattern)})
    return pd.DataFrame(records)


def _at(frame: pd.DataFrame, case: str, cell: str, ratio: float) -> pd.DataFrame:
    return frame[(frame.case == case) & (frame.cell == cell) & np.isclose(frame.ratio, ratio)]


def _weakest_head(frame: pd.DataFrame, by: str | None) -> str:
    """One line: over the points (rows of ``frame``) where ``ours`` scores below :data:`BELOW`, per value of the
    column ``by`` (all together for None), its weakest head (mean accuracy) and where most of its wrong picks point;
    "" when it fails nowhere or the runs logged no heads."""
    ours = frame[(frame.method == "ours") & (frame.sr_mean < BELOW)]
    if ours.empty or not set(DIAGNOSTICS) <= set(ours):
        return ""
    parts = []
    for group, part in ours.groupby(by) if by else [("", ours)]:
        heads, errors = part[list(HEADS)].mean(), part[list(PICK_ERRORS)].mean()
        parts.append(f"{str(group).upper() + ' ' if group else ''}({len(part)} points) {HEADS[heads.idxmin()]} "
                     f"{heads.min():.2f} (others {heads.drop(heads.idxmin()).min():.2f} or more), wrong picks mostly "
                     f"to {PICK_ERRORS[errors.idxmax()]} ({errors.max():.2f} of picking stages)")
    return f"Where ours scores below {BELOW}, its weakest head: " + "; ".join(parts) + "."


@register_section("fig_4_7")
def fig_4_7(runs: pd.DataFrame) -> Section:
    frame = _curves(runs)
    methods = thesis_cells(runs["method"].unique(), METHODS)
    points = [p for p in stated_points() if not _at(frame, *p).empty]
    rows, results = [], []
    for method in methods:
        row = {"method": LABELS.get(method, method)}
        for case, cell, ratio in points:
            hit = _at(frame[frame.method == method], case, cell, ratio)
            row[f"{case.upper()[:4]} {case[-1]} {cell} λ={ratio:g}"] = (
                fmt(hit.sr_mean.iloc[0], hit.sr_std.iloc[0]) if len(hit) else "–")
            if len(hit):
                one = hit.iloc[0]
                results.append({"row": point_row(method, case, ratio), "column": cell, "mean": one.sr_mean,
                                "std": one.sr_std, "n": one.seeds})
                if case == "case1" and cell == "4of5":  # the thesis' "handles ... unseen configurations"
                    demos = f", {one.n_train_demos:.0f} demonstrations" if "n_train_demos" in one else ""
                    results.append({"row": point_row(method, case, ratio), "column": "",
                                    "text": f"{fmt(one.sr_mean, one.sr_std)}{demos}",
                                    "met": within(one.sr_mean, math.nan, 1, 1.0, None, True)})
        rows.append(row)
    text = ("Success rate at the thesis' stated points of the training ratio λ (every point, with the per-head "
            "accuracies: the CSV and the figure). CASE 1 tests unseen goal configurations (all seen at λ = 1); "
            f"CASE 2 {amount(runs, 'protocol.case2_tests', 'human-intervention scenarios')}. "
            f"{over_seeds(runs, start=True)}. Variants of ours: `experiment=ch4/fig_4_7_variants`.")
    lines = [text, "", markdown_table(pd.DataFrame(rows))]
    weakest = _weakest_head(frame, "case")
    lines += ["", weakest] if weakest else []
    cells = thesis_cells(runs["cell"].unique(), CELLS)
    return Section("Fig. 4.7: generalisation over the training ratio", "\n".join(lines), frame,
                   {"fig_4_7.png": _lambda_plot(frame, cells, methods)}, results=results_frame(results))


def _lambda_plot(frame: pd.DataFrame, cells, methods):
    """Fig. 4.7's curves, one panel per (case, cell), the thesis' stated values of ours as black stars."""
    thesis = thesis_results()["ch4"]["figure_4_7"]
    stars = {("case1", cell): (thesis["case1_ours_unseen_lambda"], sr)
             for cell, sr in thesis["case1_ours_unseen_sr"].items()}
    stars |= {("case2", cell): (FULL, sr) for cell, sr in thesis["case2_ours_sr_at_lambda_1"].items()}
    fig, axes = plt.subplots(2, len(cells), figsize=(4.2 * len(cells), 6.4), squeeze=False, sharey=True)
    for row, case in enumerate(("case1", "case2")):
        for col, cell in enumerate(cells):
            ax = axes[row, col]
            for method in methods:
                part = frame[(frame.case == case) & (frame.cell == cell) & (frame.method == method)]
                part = part.sort_values("ratio")
                variant = method in OURS_FAMILY[1:]  # issue 24's variants of ours: dashed, beside the thesis' rows
                ax.errorbar(part.ratio, part.sr_mean, yerr=None if one_seed() else part.sr_std, marker="o",
                            capsize=2, linestyle="--" if variant else "-", label=LABELS.get(method, method))
            if (case, cell) in stars:
                ax.scatter(*([v] for v in stars[case, cell]), marker="*", s=160, color="black", zorder=4,
                           label="thesis (ours)")
            ax.set_title(f"{case.upper()} {cell}")
            ax.set_xlabel("training ratio λ")
            ax.set_ylim(-0.03, 1.05)
            ax.grid(alpha=0.3)
    for row in range(2):
        axes[row, 0].set_ylabel("success rate")
    legend = {label: handle for ax in axes.flat for handle, label in zip(*ax.get_legend_handles_labels())}
    fig.legend(legend.values(), legend.keys(), loc="lower center", ncol=4, fontsize=8)  # below the panels
    fig.tight_layout(rect=(0, 0.09, 1, 1))
    return fig


# ---- Sec. 4.4.5 ----------------------------------------------------------------------------------------------

MISSING = "missing"  # the results' row suffix of the missing-products scenario (with partial demonstrations)


def scenario_row(method: str, scenario: str) -> str:
    """The results' row of ``method`` in a practical scenario: "ours missing" (column ""), "ours 3of5" (Fig. 4.17's
    test size; columns "case1", "case2")."""
    return f"{method} {scenario}"


@register_section("practical")
def practical(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch4"]["practical"]
    generalise = thesis["train_2of5_generalise"]
    partial = amount(runs, "protocol.partial_demos", "partial demos")
    trained = f"{setting(runs, 'protocol.train_selected')}of{setting(runs, 'env.n_objects')}"
    # metric -> (column label, thesis' value of ours, results row suffix, results column)
    scenarios = {"missing_without_partial_sr": ("missing, no partial demos", None, None, None),
                 "missing_sr": (f"missing, +{partial}", thesis["missing_items_3of5_sr"], MISSING, "")}
    for size in generalise:
        for case in ("case1", "case2"):
            scenarios[f"order_size_{size}_{case}_sr"] = (f"→ {size}, CASE {case[-1]}", generalise[size][case],
                                                         size, case)
    methods = thesis_cells(runs["method"].unique(), METHODS)
    rows = [{"method": "thesis (ours)", **{label: thesis_fmt(ref) for label, ref, _, _ in scenarios.values()}}]
    records, results = [], []
    for method in methods:
        part = runs[runs.method == method]
        row = {"method": LABELS.get(method, method)}
        for metric, (label, ref, suffix, column) in scenarios.items():
            mean, std = spread(part, metric)
            seeds = int(part[metric].notna().sum()) if metric in part else 0
            row[label] = fmt(mean, std) if seeds else "n/a"
            pattern = metric.removesuffix("sr") + "{}"
            records.append({"scenario": metric, "method": method, "sr_mean": mean, "sr_std": std, "seeds": seeds,
                            "thesis": ref, **_means(part, DIAGNOSTICS, pattern)})
            if seeds and suffix is not None:
                results.append({"row": scenario_row(method, suffix), "column": column, "mean": mean, "std": std,
                                "n": seeds})
        rows.append(row)
    max_missing = setting(runs, "protocol.max_missing")
    text = (f"Missing products: {amount(runs, 'protocol.missing_tests', 'tests')} in "
            f"{' / '.join(sorted(runs.cell.unique()))} with 1-{max_missing} products absent at the start, restocked "
            f"once the rest is packed (MLP and RF need a fixed input size: n/a). Order size (Fig. 4.17): one model "
            f"trained on {trained}, {amount(runs, 'protocol.test_tests', 'tests')} per size and case. "
            f"{over_seeds(runs, start=True)}; per-head accuracies: the CSV.")
    records = pd.DataFrame(records)
    weakest = _weakest_head(records.dropna(subset=["sr_mean"]), None)
    return Section("Practical scenarios (4.4.5): missing products, order size (Fig. 4.17)",
                   f"{text}\n\n{markdown_table(pd.DataFrame(rows))}" + (f"\n\n{weakest}" if weakest else ""),
                   records, results=results_frame(results))


# ---- Fig. 4.9 ------------------------------------------------------------------------------------------------


def _separable(frame: pd.DataFrame) -> str:
    """Which (case, stage) have a largest share that leads the runner-up by more than the larger of their seed
    spreads, and which do not (then the ranking cannot be told from these seeds); nothing for one seed."""
    if one_seed():
        return ""
    clear, unclear = [], []
    for (case, stage), part in frame.groupby(["case", "stage"]):
        first, second = part.sort_values("mean", ascending=False).iloc[:2].itertuples()
        where = f"{case} {stage} ({first.feature} {first.mean:.2f} vs {second.feature} {second.mean:.2f})"
        (clear if first.mean - second.mean > max(first.std, second.std) else unclear).append(where)
    parts = []
    if clear:
        parts.append(f"leads the next by more than their seed spread in {', '.join(clear)}")
    if unclear:
        parts.append(f"by less than the spread in {', '.join(unclear)}")
    return "The largest share " + "; ".join(parts) + "."


EXPECTED = {"picking": "I", "placing": "z"}  # the thesis' most important feature per stage (Sec. 4.4.1)


@register_section("fig_4_9")
def fig_4_9(runs: pd.DataFrame) -> Section:
    columns = [c for c in runs.columns if "_importance_" in c]
    frame = runs[columns].agg(["mean", lambda c: c.std(ddof=0)]).T.set_axis(["mean", "std"], axis=1).reset_index()
    frame[["case", "stage", "feature"]] = frame["index"].str.extract(r"(case\d)_(\w+)_importance_(\w+)")
    features = [f for f in ("x", "y", "z", "I") if f in set(frame.feature)]
    frame["value"] = [fmt(m, s) for m, s in zip(frame["mean"], frame["std"])]
    table = frame.pivot(index=["case", "stage"], columns="feature", values="value").reindex(columns=features)
    table = table.fillna("–")  # a feature a stage logged no share for
    top = frame.loc[frame.groupby(["case", "stage"])["mean"].idxmax()].set_index(["case", "stage"])["feature"]
    cases = sorted(frame.case.unique())
    shown = "; ".join(f"{stage}: {' / '.join(top.get((case, stage), '–') for case in cases)}"
                      for stage in EXPECTED)
    met = all(top.get((case, stage)) == feature for case in cases for stage, feature in EXPECTED.items())
    seed = runs.sort_values("seed").iloc[0]
    text = [
        "GNNExplainer feature masks of `ours`' P_o output, summed over nodes and normalised (each feature's share). "
        f"{over_seeds(runs, start=True)}; the masks below: seed {seed.seed}.",
        "",
        markdown_table(table.reset_index()),
        "",
        f"Largest share per stage ({' / '.join(c.upper() for c in cases)}): {shown}. {_separable(frame)}".rstrip(),
    ]
    artifacts = {f"fig_4_9_case{c}.png": (seed.run_id, f"plots/fig_4_9_case{c}.png") for c in (1, 2)}
    csv = frame[["case", "stage", "feature", "mean", "std"]].rename(columns={"mean": "importance_mean",
                                                                         "std": "importance_std"})
    results = [{"row": "ours", "column": "", "text": f"largest share {shown}", "met": met}]
    return Section("Fig. 4.9: GNNExplainer masks", "\n".join(text), csv, {}, artifacts,
                   results=results_frame(results))


# ---- the plan ------------------------------------------------------------------------------------------------

_FIG_4_7 = thesis_results()["ch4"]["figure_4_7"]
_CASE1, _UNSEEN, _CASE2 = stated_points()[0], stated_points()[1], stated_points()[2]
P_O = "P_o at picking, the mean readout's, fails"  # what the Fig. 4.7 and Fig. 4.17 sections' last lines show


def _ours(study: str, row) -> dict:
    """The as-written and ★ picks of a reasoning row: ``ours`` and hrc_lab's module (``hrc``)."""
    return {"as_written": Pick(study, row("ours")), "star": Pick(study, row("hrc"), "hrc_lab's module")}


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch4_reasoning",
    title="Ch.4 reasoning module (GraphSAGE importance ranking) vs. baselines",
    note="Our scenes come from the simulator-independent package-to-order spec (`hrc_lab/env/robot/spec.py`), "
         "not the thesis' CoppeliaSim scenes; ★ is hrc_lab's reasoning module (`reasoning=hrc`, docs/chapters/ch4.md).",
    studies=(
        Study("ch4/table_4_1"),
        Study("ch4/fig_4_7", also=("ch4/fig_4_7_variants",)),
        Study("ch4/practical"),
        Study("ch4/fig_4_9"),
        Study("ch4/table_4_1", ("env=package_to_order_3of5,package_to_order_4of5", "reasoning=ours,mlp",
                                "reasoning.position_frame=world_m", "reasoning.steps=3000"),
              key="mlp_world_frame", title="Table 4.1's MLP and ours on positions in the world frame, in metres",
              question="Does the thesis' MLP gap at 3of5 and 4of5 appear when positions are not centred?"),
        Study("ch4/table_4_1", ("env=package_to_order_3of5,package_to_order_4of5", "reasoning=gnn_task",
                                "reasoning.steps=4000"),
              key="gnn_task_steps", title="Table 4.1's GNN-task with a longer training",
              question="Is GNN-task's drop at 3of5 and 4of5 a plateau of its training within the shared budget?"),
    ),
    rows=(
        Row("Table 4.1", "Ours", "ch4.table_4_1.ours", **_ours("table_4_1", lambda m: m)),
        Row("Table 4.1", "GNN [74]", "ch4.table_4_1.gnn", Pick("table_4_1", "gnn")),
        Row("Table 4.1", "GNN-task", "ch4.table_4_1.gnn_task", Pick("table_4_1", "gnn_task"),
            why="P_g at placing has not fit its training stages in the shared budget "
                "([longer training](#gnn_task_steps))"),
        Row("Table 4.1", "MLP", "ch4.table_4_1.mlp", Pick("table_4_1", "mlp"),
            why="our positions are centred on the table ([uncentred](#mlp_world_frame))"),
        Row("Table 4.1", "RF", "ch4.table_4_1.rf", Pick("table_4_1", "rf")),
        Row("Fig. 4.7", f"Ours, CASE 1, unseen configurations, λ = {_CASE1[2]:g}",
            "ch4.figure_4_7.case1_ours_unseen_sr",
            **_ours("fig_4_7", lambda m: point_row(m, _CASE1[0], _CASE1[2])),
            why=f"{P_O} on unseen selections ([variants](#fig_4_7))"),
        Row("Fig. 4.7", f"Ours, CASE 2, λ = {_CASE2[2]:g}", "ch4.figure_4_7.case2_ours_sr_at_lambda_1",
            **_ours("fig_4_7", lambda m: point_row(m, _CASE2[0], _CASE2[2])),
            why=f"{P_O}: it predicts a placing stage after a human's packing"),
        Row("Fig. 4.7", f"Ours, CASE 1, 4of5, λ = {_UNSEEN[2]:g}", "", claim=(
            f"handles {_FIG_4_7['case1_4of5_unseen_configs_handled']} unseen goal configurations with "
            f"{_FIG_4_7['case1_4of5_trained_demos']} trained demonstrations"),
            **_ours("fig_4_7", lambda m: point_row(m, _UNSEEN[0], _UNSEEN[2])), why=f"{P_O} on unseen selections"),
        Row("Sec. 4.4.5", "Ours, products missing, retrained with partial demos",
            "ch4.practical.missing_items_3of5_sr", **_ours("practical", lambda m: scenario_row(m, MISSING))),
        *(Row("Fig. 4.17", f"Ours, trained 2of5, tested {size}", f"ch4.practical.train_2of5_generalise.{size}",
              **_ours("practical", lambda m, size=size: scenario_row(m, size)),
              why=f"{P_O} on orders larger than trained")
          for size in thesis_results()["ch4"]["practical"]["train_2of5_generalise"]),
        Row("Fig. 4.9", "Feature masks", "", claim="I decisive at picking, z at placing, the same masks in CASE 1 "
            "and CASE 2", as_written=Pick("fig_4_9", "ours")),
    ),
)
