"""Report sections of the Ch.6 grasp-solution experiments: Table 6.1 and the single-image row of Table 6.2."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from hrc_lab.report.runs import setting, setting_number, spread  # noqa: E402
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, thesis_results  # noqa: E402

METHODS = {
    "gnn_att": "GNN_Att (ours)",
    "gnn_att_oracle": "GNN_Att, ground-truth boxes (ablation)",
    "gnn_att_wo_we": "GNN_Att w/o WE",
    "gnn_lstm": "GNN_LSTM",
    "gnn_df_att": "GNN_DF_Att",
    "gvmrn_rf": "GVMRN_RF",
    "gcn_att": "GCN_Att",
}
COLUMNS = [("train_grasp_acc", "Train_Acc"), ("oa_1", "one type"), ("oa_2", "two types"), ("oa_3", "three types")]


@register_section("table_6_1")
def table_6_1(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch6"]["table_6_1"]
    methods = [m for m in METHODS if m in set(runs.method)]
    rows, records = [], []
    for method in methods:
        row = {"method": METHODS[method]}
        for (metric, title), ref in zip(COLUMNS, thesis.get(method, [[None, None]] * len(COLUMNS))):  # ablations
            mean, std = spread(runs[runs.method == method], metric)
            row[title] = f"{fmt(mean, std, 3)} ({fmt(*ref, 3)})"
            records.append({"method": method, "metric": metric, "mean": mean, "std": std})
        rows.append(row)
    text = [
        "Object accuracy (OA): a requested part counts when it is detected, its graspability is right and, when it "
        "is not graspable, the decoded solution is right; on the unseen test scenes with new random requests of "
        "one, two or three part types. Train_Acc: graspability accuracy on the training scenes. Mean ± std over "
        f"seeds {sorted(runs.seed.unique())}; thesis values in brackets. Node features: the detector's box-head "
        f"feature of each box{_context(runs)}, the label and the request flag (GVMRN_RF classifies pairs from "
        "union-box features). The ground-truth-box row "
        "reads the same network's features from the true boxes: its gap to ours is what detection errors cost.",
        "",
        pd.DataFrame(rows).to_markdown(index=False),
    ]
    frame = pd.DataFrame(records)
    return Section(
        "Table 6.1: object accuracy on single images", "\n".join(text), frame, {"table_6_1.png": _bars(frame)}
    )


def _context(runs: pd.DataFrame) -> str:
    """How the runs' node features use the enlarged box (``grasp.detector.context_scale``, not in the thesis)."""
    key = "grasp.detector.context_scale"
    scale = setting_number(runs, key)
    if scale is None:
        return f" and of the box enlarged by `{key}` ({setting(runs, key)}; not in the thesis)"
    if scale == 0:
        return f" only (no enlarged-box feature: `{key}` = 0)"
    return f" and of the box enlarged {scale:g}× (`{key}`, not in the thesis)"


def _bars(frame: pd.DataFrame):
    fig, ax = plt.subplots(figsize=(7, 3.6))
    methods = list(dict.fromkeys(frame.method))
    metrics = [m for m, _ in COLUMNS[1:]]
    width = 0.8 / max(1, len(methods))
    for i, method in enumerate(methods):
        part = frame[frame.method == method].set_index("metric").reindex(metrics)
        xs = [j + i * width for j in range(len(metrics))]
        ax.bar(xs, part["mean"], width, yerr=part["std"], capsize=2, label=METHODS[method])
    ax.set_xticks([j + 0.4 - width / 2 for j in range(len(metrics))], [t for _, t in COLUMNS[1:]])
    ax.set_ylabel("object accuracy")
    ax.set_ylim(0, 1.05)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    return fig


@register_section("table_6_2_single")
def table_6_2_single(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch6"]["table_6_2"]
    counts = sorted(int(c[len("acc_") :]) for c in runs.columns if c.startswith("acc_"))
    rows, records = [], []
    for method in [m for m in METHODS if m in set(runs.method)]:
        row = {"method": METHODS[method]}
        for count in counts:
            mean, std = spread(runs[runs.method == method], f"acc_{count}")
            ref = thesis["single_image"][thesis["columns"].index(str(count))] if method == "gnn_att" else None
            row[f"{count} objects"] = fmt(mean, std, 3) + (f" ({ref})" if ref is not None else "")
            records.append({"method": method, "objects": count, "mean": mean, "std": std})
        rows.append(row)
    text = [
        "Algorithm 4 on one image: for a random requested part type, the solver checks the requested parts; when "
        "none is graspable, the decoded solution's part types (nearest detected part of each) become the new "
        "request, until a graspable part or help. Right when the final grasp is a part the labelling rule finds "
        "graspable among the requested parts (or, if none is, among those the rule's own iteration reaches), or "
        f"when both end in help. Mean ± std over seeds {sorted(runs.seed.unique())}; thesis (single image, 10 "
        "cases per count, checked by hand) in brackets.",
        "",
        pd.DataFrame(rows).to_markdown(index=False),
    ]
    ours = runs[runs.method == "gnn_att"]
    artifacts = {}
    if len(ours) and "examples_logged" in ours:
        artifacts["examples.png"] = (ours.iloc[0].run_id, "figures/examples.png")
    return Section(
        "Table 6.2 (single-image row): iterative grasping solutions",
        "\n".join(text),
        pd.DataFrame(records),
        {},
        artifacts,
    )
