"""Report sections of the Ch.6 grasp-solution experiments: Table 6.1, the single-image row of Table 6.2, Table 6.3
(on our scenes in VMRD's layout) and Fig. 6.9 (its two stages over the number of object types). Each shows one
table; the measurements that explain it (:mod:`hrc_lab.grasp.diagnostics`: where the object accuracy is lost, the
scenes' geometry against GNN_DF_Att's distance filter, why Algorithm 4's answers are wrong) go to its CSV."""

from __future__ import annotations

import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from hrc_lab.grasp.diagnostics import FAILURE_CAUSES, GEOMETRY_METRICS  # noqa: E402
from hrc_lab.report.headline import results_frame  # noqa: E402
from hrc_lab.report.plan import Pick, Plan, Row, Study  # noqa: E402
from hrc_lab.report.runs import (  # noqa: E402
    amount,
    histories,
    keyed,
    over_seeds,
    run_tables,
    setting,
    setting_number,
    spread,
)
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, markdown_table, thesis_results  # noqa: E402

METHODS = {
    "gnn_att": "GNN_Att",
    "gnn_att_oracle": "GNN_Att, ground-truth boxes",
    "gnn_att_wo_we": "GNN_Att w/o WE",
    "gnn_lstm": "GNN_LSTM",
    "gnn_df_att": "GNN_DF_Att",
    "gvmrn_rf": "GVMRN_RF",
    "gcn_att": "GCN_Att",
    "vmrn": "VMRN",
    "gnn_att_depth": "GNN_Att + depth (thesis' future work)",
    "gnn_transformer": "GNN_Transformer (thesis' future work)",
    "gnn_rel_att": "GNN_Rel_Att (hrc_lab)",
    "gnn_rel_att_depth": "★ GNN_Rel_Att + depth (hrc_lab)",
    "rule": "the labelling rule as the solver",
}
STAR = "gnn_rel_att_depth"
# Table 6.1's metrics and the thesis' columns (thesis_results.yaml ch6.table_6_1.columns) they stand for
COLUMNS = {"train_grasp_acc": ("train_acc", "Train_Acc"), "oa_1": ("one_type", "one type"),
           "oa_2": ("two_types", "two types"), "oa_3": ("three_types", "three types")}
REQUEST_SIZES = (1, 2, 3)
SOLVER_CURVE = "solver/-train_grasp_acc"  # Lightning's per-epoch mean while training (prefix "solver/")
FIT_TARGET = 0.99  # issue 20: the solver must fit its training scenes before test accuracy is compared


def _records(runs: pd.DataFrame, methods: list[str], metrics: list[str], column=lambda metric: metric) -> list[dict]:
    """One record per (method, metric): mean, std (over seeds) and n; ``column(metric)``: its thesis column."""
    records = []
    for method in methods:
        part = runs[runs.method == method]
        for metric in metrics:
            mean, std = spread(part, metric)
            n = int(part[metric].notna().sum()) if metric in part else 0
            records.append({"method": method, "metric": metric, "row": method, "column": column(metric),
                            "mean": mean, "std": std, "n": n})
    return records


def _methods(runs: pd.DataFrame) -> list[str]:
    return [m for m in METHODS if m in set(runs.method)]


def _pooled(runs: pd.DataFrame, stem: str) -> pd.Series:
    """Per run, the mean of ``<stem>_1..3`` (the three request sizes, each over its own test requests)."""
    columns = [f"{stem}_{k}" for k in REQUEST_SIZES if f"{stem}_{k}" in runs]
    return runs[columns].mean(axis=1) if columns else pd.Series(float("nan"), index=runs.index)


@register_section("table_6_1")
def table_6_1(runs: pd.DataFrame) -> Section:
    methods = _methods(runs)
    runs = runs.assign(test_detected=_pooled(runs, "detected"), test_fit=_pooled(runs, "fit_acc"),
                       test_oa=_pooled(runs, "oa"))
    shown = {**{metric: title for metric, (_, title) in COLUMNS.items()},
             "test_detected": "test: detected", "test_fit": "test: graspability (detected)"}
    diagnostics = ["train_detected", "train_part_grasp_acc", "test_oa",
                   *sorted(c for c in runs.columns if c.startswith("oa_type_")),
                   *[c for c in GEOMETRY_METRICS if c in runs]]
    records = _records(runs, methods, [*shown, *diagnostics], lambda m: COLUMNS.get(m, (m,))[0])
    frame = pd.DataFrame(records)
    rows = [{"method": METHODS[method]} | {title: fmt(hit["mean"], hit["std"], 3) for title, hit in zip(
        shown.values(), (frame[(frame.method == method) & (frame.metric == m)].iloc[0] for m in shown))}
        for method in methods]
    text = [
        "OA: a requested part counts when it is detected, its graspability is right and, if it cannot be grasped, "
        f"its decoded solution; {amount(runs, 'protocol.test_images', 'unseen test scenes')}, requests of 1-3 part "
        f"types. Train_Acc: graspability on the detected training parts. {over_seeds(runs, start=True)}; "
        f"{amount(runs, 'protocol.train_images', 'training scenes')}; node features: the box{_context(runs)}.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    figures = {"table_6_1.png": _bars(frame[frame.metric.isin(["oa_1", "oa_2", "oa_3"])])}
    curve = _solver_curve(runs[runs.method == "gnn_att"])
    if curve is not None:
        figures["solver_curve.png"] = curve
    ours = runs[runs.method == "gnn_att"]
    artifacts = {}
    if len(ours) and "geometry_blockers_within_filter" in ours:
        artifacts["geometry.png"] = (ours.iloc[0].run_id, "figures/geometry.png")
    results = results_frame([r for r in records if r["metric"] in COLUMNS])
    return Section("Table 6.1: object accuracy on single images", "\n".join(text),
                   frame.drop(columns=["row", "column"]), figures, artifacts, results=results)


def _solver_curve(runs: pd.DataFrame):
    """The solver's graspability accuracy per epoch while training, one line per run; None without histories."""
    history = histories(runs, SOLVER_CURVE)
    if history.empty:
        return None
    fig, ax = plt.subplots(figsize=(5, 3))
    for seed, part in history.merge(runs[["run_id", "seed"]], on="run_id").groupby("seed"):
        ax.plot(part.step, part.value, label=f"seed {seed}")
    ax.axhline(FIT_TARGET, color="k", linestyle="--", linewidth=1)
    ax.set_xlabel("gradient step")
    ax.set_ylabel("GNN_Att: train graspability accuracy")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _context(runs: pd.DataFrame) -> str:
    """How the runs' node features use the enlarged box (``grasp.detector.context_scale``, not in the thesis)."""
    key = "grasp.detector.context_scale"
    scale = setting_number(runs, key)
    if scale is None:
        return f" and the box enlarged by `{key}` ({setting(runs, key)}; not in the thesis)"
    if scale == 0:
        return f" only (no enlarged-box feature: `{key}` = 0)"
    return f" and the box enlarged {scale:g}× (`{key}`, not in the thesis)"


def _bars(frame: pd.DataFrame):
    fig, ax = plt.subplots(figsize=(7, 3.6))
    methods = list(dict.fromkeys(frame.method))
    metrics = ["oa_1", "oa_2", "oa_3"]
    width = 0.8 / max(1, len(methods))
    for i, method in enumerate(methods):
        part = frame[frame.method == method].set_index("metric").reindex(metrics)
        xs = [j + i * width for j in range(len(metrics))]
        ax.bar(xs, part["mean"], width, yerr=part["std"], capsize=2, label=METHODS[method])
    ax.set_xticks([j + 0.4 - width / 2 for j in range(len(metrics))], [COLUMNS[m][1] for m in metrics])
    ax.set_ylabel("object accuracy")
    ax.set_ylim(0, 1.05)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    return fig


@register_section("table_6_2_single")
def table_6_2_single(runs: pd.DataFrame) -> Section:
    counts = sorted(int(c[len("acc_"):]) for c in runs.columns if re.fullmatch(r"acc_\d+", c))
    methods = _methods(runs)
    accuracy = _records(runs, methods, [f"acc_{n}" for n in counts], lambda m: m[len("acc_"):])
    failures = _records(runs, methods, [f"fail_{cause}_{n}" for cause in FAILURE_CAUSES for n in counts
                                        if f"fail_{cause}_{n}" in runs], lambda m: m.rsplit("_", 1)[1])
    rows = [{"method": METHODS[method]} | {f"{r['column']} objects": fmt(r["mean"], r["std"], 3)
                                           for r in accuracy if r["method"] == method} for method in methods]
    text = [
        "Algorithm 4 on one image: for a random requested part type the solver checks the requested parts; when "
        "none is graspable, the decoded solution's types become the request, until a graspable part or help. Right "
        f"when it ends where the labelling rule's own Algorithm 4 does; {amount(runs, 'protocol.cases', 'scenes')} "
        f"per part count. {over_seeds(runs, start=True)}. Why answers are wrong and how many requests they took: "
        "the CSV.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    artifacts = {}
    ours = runs[runs.method == "gnn_att"]
    if len(ours) and "examples_logged" in ours:
        artifacts["examples.png"] = (ours.iloc[0].run_id, "figures/examples.png")
    table = pd.concat([pd.DataFrame(accuracy + failures), _answer_lengths(runs)], ignore_index=True)
    return Section("Table 6.2 (single-image row): iterative grasping solutions", "\n".join(text),
                   table.drop(columns=["row"]).rename(columns={"column": "objects"}).astype({"objects": int}), {},
                   artifacts,
                   results=results_frame(accuracy))


def _answer_lengths(runs: pd.DataFrame) -> pd.DataFrame:
    """How many requests Algorithm 4 made per answer, and the rule's own chain, per method and part count, over
    every case of the runs' ``table_6_2_single`` tables (``mean`` over cases; no spread)."""
    cases = run_tables(runs, "table_6_2_single")
    if cases.empty:
        return pd.DataFrame()
    cases = cases.merge(runs[["run_id", "method"]], on="run_id")
    measures = {"requests_per_answer": ("iterations", "mean"),
                "answered_at_first_request": ("iterations", lambda n: (n == 1).mean()),
                "help": ("help", "mean"), "rule_requests": ("rule_requests", "mean"),
                "rule_one_request_enough": ("rule_requests", lambda n: (n == 1).mean()), "n": ("correct", "size")}
    lengths = cases.groupby(["method", "objects"]).agg(**measures).reset_index()
    tidy = lengths.melt(["method", "objects", "n"], var_name="metric", value_name="mean")
    return tidy.assign(column=tidy.objects.astype(int).astype(str), std=float("nan")).drop(columns="objects")


@register_section("table_6_3")
def table_6_3(runs: pd.DataFrame) -> Section:
    facts = thesis_results()["ch6"]["text"]
    counts = sorted(int(c[len("ia_"):]) for c in runs.columns if re.fullmatch(r"ia_\d+", c))
    methods = _methods(runs)
    records = _records(runs, methods, ["ia", *[f"ia_{n}" for n in counts], "oa"],
                       lambda m: "" if m == "ia" else m)
    frame = pd.DataFrame(records)
    titles = {"ia": "IA", **{f"ia_{n}": f"IA, {n} objects" for n in counts}, "oa": "object accuracy"}
    rows = [{"method": METHODS[method]} | {titles[r.metric]: fmt(r.mean, r.std, 3)
                                           for r in frame[frame.method == method].itertuples()} for method in methods]
    written = bool(runs["written_by_hrc_lab"].min()) if "written_by_hrc_lab" in runs else True
    source = (f"our {amount(runs, 'protocol.train_images', 'trainval')} and "
              f"{amount(runs, 'protocol.test_images', 'test')} rendered scenes in VMRD v2's layout (the rule's "
              f"blockers as children), not VMRD v2 ({facts['vmrd_object_types_in_test']} classes), which cannot "
              "be downloaded here" if written
              else f"`{setting(runs, 'env.vmrd_root')}`, {_classes(runs)} classes, letterboxed to "
                   f"{keyed(runs, 'env.image_size', 'px')}")
    text = [
        "IA (6.4.2): a test image counts when every object in it is detected, with the right graspability and, if "
        "it cannot be grasped, the right solution; VMRN classifies every pair of detected objects as parent / child "
        f"/ none. Data: {source}. {over_seeds(runs, start=True)}.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    return Section("Table 6.3: image-based accuracy " + ("(our scenes in VMRD's layout)" if written else
                                                        "(a data set in VMRD's layout)"), "\n".join(text),
                   frame.drop(columns=["row", "column"]), results=results_frame(frame[frame.metric == "ia"].to_dict(
                       "records")))


def _classes(runs: pd.DataFrame) -> str:
    """How many classes the runs' data set has ("31"), from their ``classes`` metric."""
    counts = sorted({int(n) for n in runs["classes"].dropna()}) if "classes" in runs else []
    return " or ".join(map(str, counts)) if counts else "its"


TYPES_METRIC = re.compile(r"types(\d+)_grasp_ia")  # Fig. 6.9's runs log types<k>_<name> per number of types k
STAGES = {"grasp_ia": "GNN: graspability", "solution_ia": "LSTM_Att: solutions"}
CLAIM = "types"  # the row of Fig. 6.9's results: the thesis' statement on our curves


@register_section("fig_6_9")
def fig_6_9(runs: pd.DataFrame) -> Section:
    """Fig. 6.9: the image-based accuracy of the graspability classification and of the decoded solutions per number
    of object types k (``types<k>_*`` metrics of :func:`hrc_lab.experiments.ch6_grasp.fig_6_9`), over all test
    images and over those of the one object count every k has."""
    counts = sorted(int(m.group(1)) for c in runs.columns if (m := TYPES_METRIC.fullmatch(c)))
    methods = ", ".join(METHODS.get(m, m) for m in sorted(set(runs.method)))
    shared = _shared_count(runs, counts)
    metrics = ["test_images", "objects", *STAGES, *([f"{stage}_n{shared}" for stage in STAGES] if shared else []),
               "ia", "train_grasp_acc"]
    records = [{"types": k, "metric": metric, "mean": mean, "std": std}
               for k in counts for metric in metrics for mean, std in [spread(runs, f"types{k}_{metric}")]]
    frame = pd.DataFrame(records, columns=["types", "metric", "mean", "std"])
    value = {(r.types, r.metric): (r.mean, r.std) for r in frame.itertuples()}
    rows = []
    for k in counts:
        row = {"object types": k, "test images": fmt(value[k, "test_images"][0], None, 0),
               "objects per image": fmt(value[k, "objects"][0], None, 2)}
        row |= {f"{title} IA": fmt(*value[k, stage], 3) for stage, title in STAGES.items()}
        if shared:
            row |= {f"{title}, {shared} objects": fmt(*value[k, f"{stage}_n{shared}"], 3)
                    for stage, title in STAGES.items()}
        rows.append(row)
    text = [
        f"{methods} trained and tested on data sets of k object types, every object requested. GNN: test images "
        "whose every object is detected with the right graspability; LSTM_Att: of the images with an object that "
        "cannot be grasped, those whose every such object is decoded right. Our scenes keep the k most numerous part "
        f"types, so k also adds objects (last columns: the {shared}-object images). "
        f"{over_seeds(runs, start=True)}.",
        "",
        markdown_table(pd.DataFrame(rows)) if rows else "(no runs)",
    ]
    figures = {"fig_6_9.png": _stages_figure(frame, methods)} if records else {}
    return Section("Fig. 6.9: graspability and solutions over the number of object types", "\n".join(text), frame,
                   figures, results=results_frame([_claim(value, counts, runs.seed.nunique())]))


def _shared_count(runs: pd.DataFrame, counts: list[int]) -> int | None:
    """The smallest object count whose test images every k has (``types<k>_grasp_ia_n<n>``), None if none."""
    present = [{int(c.rsplit("_n", 1)[1]) for c in runs.columns if c.startswith(f"types{k}_grasp_ia_n")}
               for k in counts]
    shared = sorted(set.intersection(*present)) if present else []
    return shared[0] if shared else None


def _claim(value: dict, counts: list[int], seeds: int) -> dict:
    """The thesis' statement (the GNN's accuracy "does not decrease a lot while the LSTM_Att's performance drops")
    on our curves, from the fewest to the most types: met when the solutions' IA falls, and by more than the
    graspability's."""
    if len(counts) < 2:
        return {"row": CLAIM, "column": "", "text": "", "met": None}
    first, last = counts[0], counts[-1]
    drop = {stage: value[first, stage][0] - value[last, stage][0] for stage in STAGES}
    text = f"k {first} → {last}: " + ", ".join(
        f"{title.split(':')[0]} {value[first, stage][0]:.2f} → {value[last, stage][0]:.2f}"
        for stage, title in STAGES.items())
    return {"row": CLAIM, "column": "", "text": text, "n": seeds,
            "met": bool(drop["solution_ia"] > 0 and drop["solution_ia"] > drop["grasp_ia"])}


def _stages_figure(frame: pd.DataFrame, methods: str):
    """Fig. 6.9's plot: each stage's image-based accuracy over the number of object types, mean ± std over seeds."""
    fig, ax = plt.subplots(figsize=(5, 3.2))
    for stage, title in STAGES.items():
        part = frame[frame.metric == stage]
        ax.errorbar(part.types, part["mean"], yerr=part["std"], marker="o", capsize=3, label=title)
    ax.set_xlabel("object types in the data set")
    ax.set_ylabel("image-based accuracy")
    ax.set_ylim(0, 1.05)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title(methods, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _table_6_1_row(method: str, name: str, why: str, star: bool = False, columns: tuple[str, ...] = ()) -> Row:
    return Row("Table 6.1", name, f"ch6.table_6_1.{method}", Pick("table_6_1", method),
               star=Pick("table_6_1", STAR, "GNN_Rel_Att + depth") if star else None, columns=columns, why=why)


SCRATCH = "our detector is trained from scratch on rendered scenes, not pretrained"
CONTEXT = "our node features add an enlarged box (not in the thesis)"

# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch6_grasp",
    title="Ch.6 iterative visual grasping: graspability and grasp solutions from detector features",
    note="Scenes are rendered in MuJoCo (parts a, b, c dropped with physics), labelled by one geometric rule, "
         "not photos labelled by an expert; the detector is a small Faster R-CNN trained from scratch.",
    studies=(
        Study("ch6/table_6_1"),
        Study("ch6/table_6_2_single"),
        Study("ch6/table_6_3"),
        Study("ch6/fig_6_9"),
        Study("ch6/table_6_1", ("grasp=gnn_att,gnn_rel_att_depth", "protocol.train_images=3416"), key="train_images",
              title="Table 6.1 with more training scenes",
              question="Does the object accuracy approach the thesis' when the detector and the solver learn from "
                       "more rendered scenes than the thesis had?"),
        Study("ch6/table_6_1", ("grasp=gnn_att,gnn_att_wo_we,gnn_df_att", "grasp.detector.context_scale=0"),
              key="no_context", title="Table 6.1 without the enlarged-box feature (node features as the thesis')",
              question="Why do GNN_Att w/o WE and GNN_DF_Att trail GNN_Att by less than in the thesis?"),
    ),
    rows=(
        _table_6_1_row("gnn_att", "GNN_Att", f"{SCRATCH} ([more scenes](#train_images))", star=True),
        _table_6_1_row("gnn_att_wo_we", "GNN_Att w/o WE",
                       f"{CONTEXT}, seeing the neighbours ([without it](#no_context))"),
        _table_6_1_row("gnn_lstm", "GNN_LSTM", SCRATCH),
        _table_6_1_row("gnn_df_att", "GNN_DF_Att",
                       f"{CONTEXT}, seeing what the filter drops ([without it](#no_context))"),
        _table_6_1_row("gvmrn_rf", "GVMRN_RF", "pairs read from our detector's union-box features; no thesis Train_Acc",
                       columns=("one_type", "two_types", "three_types")),
        _table_6_1_row("gcn_att", "GCN_Att", SCRATCH),
        Row("Table 6.2", "Single image", "ch6.table_6_2.single_image", Pick("table_6_2_single", "gnn_att"),
            star=Pick("table_6_2_single", STAR, "GNN_Rel_Att + depth"),
            why="scored against the labelling rule on rendered scenes, not checked by hand"),
        *(Row("Table 6.3", METHODS[method], f"ch6.table_6_3.{method}", Pick("table_6_3", method), why=why)
          for method, why in (("vmrn", "our rendered scenes in VMRD's layout, not VMRD v2 (it cannot be downloaded "
                                       "here)"), ("gvmrn_rf", "as VMRN's"), ("gnn_att", "as VMRN's"))),
        Row("Fig. 6.9", "GNN and LSTM_Att over the object types", "", Pick("fig_6_9", CLAIM),
            claim="the GNN's accuracy \"does not decrease a lot while the LSTM_Att's performance drops\" (6.4.2)",
            why="our parts a, b, c, not VMRD's classes; more types also mean more objects per image"),
    ),
)
