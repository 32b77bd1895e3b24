"""Report sections of the Ch.6 grasp-solution experiments: Table 6.1, the single-image row of Table 6.2, Table 6.3
(on our scenes in VMRD's layout) and Fig. 6.9 (its two stages over the number of object types), with the
measurements that explain them (:mod:`hrc_lab.grasp.diagnostics`):
where the object accuracy is lost (detection, the solver's fit, the hardest part type), the solver's training curve,
the scenes' geometry against GNN_DF_Att's distance filter, and the causes of Algorithm 4's wrong answers."""

from __future__ import annotations

import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from hrc_lab.grasp.diagnostics import FAILURE_CAUSES  # noqa: E402
from hrc_lab.report.defaults import PARAM_PREFIX  # noqa: E402
from hrc_lab.report.plan import Plan, Study  # noqa: E402
from hrc_lab.report.runs import (  # noqa: E402
    DEFAULT_VARIANT,
    amount,
    fetch_runs,
    finished_runs,
    histories,
    keyed,
    over_seeds,
    run_tables,
    setting,
    setting_number,
    spread,
)
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, markdown_table, thesis_fmt, thesis_results, thesis_value  # noqa: E402

METHODS = {
    "gnn_att": "GNN_Att (ours)",
    "gnn_att_oracle": "GNN_Att, ground-truth boxes (ablation)",
    "gnn_att_wo_we": "GNN_Att w/o WE",
    "gnn_lstm": "GNN_LSTM",
    "gnn_df_att": "GNN_DF_Att",
    "gvmrn_rf": "GVMRN_RF",
    "gcn_att": "GCN_Att",
    "vmrn": "VMRN",
    "gnn_att_depth": "★ GNN_Att + depth (beyond the thesis)",
    "gnn_transformer": "★ GNN_Transformer (beyond the thesis)",
    "gnn_rel_att": "★ GNN_Rel_Att: relational messages and blockers (hrc_lab)",
    "gnn_rel_att_depth": "★ GNN_Rel_Att + depth (hrc_lab)",
    "rule": "the labelling rule as the solver, the learned solvers' ceiling",
}
COLUMNS = [("train_grasp_acc", "Train_Acc"), ("oa_1", "one type"), ("oa_2", "two types"), ("oa_3", "three types")]
REQUEST_SIZES = (1, 2, 3)
SOLVER_CURVE = "solver/-train_grasp_acc"  # Lightning's per-epoch mean while training (prefix "solver/")
FIT_TARGET = 0.99  # issue 20: the solver must fit its training scenes before test accuracy is compared


@register_section("table_6_1")
def table_6_1(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch6"]["table_6_1"]
    methods = [m for m in METHODS if m in set(runs.method)]
    rows, records = [], []
    for method in methods:
        row = {"method": METHODS[method]}
        for (metric, title), ref in zip(COLUMNS, thesis.get(method, [[None, None]] * len(COLUMNS))):  # ablations
            mean, std = spread(runs[runs.method == method], metric)
            row[title] = f"{fmt(mean, std, 3)} ({thesis_fmt(*ref, 3)})"
            records.append({"method": method, "metric": metric, "mean": mean, "std": std})
        rows.append(row)
    text = [
        "Object accuracy (OA): a requested part counts when it is detected, its graspability is right and, when it "
        "is not graspable, the decoded solution is right; on the unseen test scenes with new random requests of "
        "one, two or three part types. Train_Acc: the solver's graspability accuracy on the requested parts of its "
        "training scenes that the detector found (the nodes it is trained on). "
        f"{over_seeds(runs, start=True)}; thesis values in brackets. Node features: the detector's box-head "
        f"feature of each box{_context(runs)}, the label and the request flag (GVMRN_RF classifies pairs from "
        "union-box features). The ground-truth-box row "
        "reads the same network's features from the true boxes: its gap to ours is what detection errors cost.",
        "",
        markdown_table(pd.DataFrame(rows)),
        "",
        *_decomposition(runs, methods, thesis_results()["ch6"]["text"]["part_a_object_accuracy"]),
        *_geometry(runs, thesis_results()["ch6"]["text"]),
    ]
    figures = {"table_6_1.png": _bars(pd.DataFrame(records))}
    curve = _solver_curve(runs[runs.method == "gnn_att"])
    if curve is not None:
        figures["solver_curve.png"] = curve
        text += ["", "The solver's training curve (GNN_Att, graspability accuracy on its training nodes per epoch, "
                 f"one line per seed; dashed: {FIT_TARGET}):"]
    sizes = _training_set_sizes(runs)
    if sizes is not None:
        table, figure = sizes
        figures["training_images.png"] = figure
        text += ["", "Over the number of training images (this section's runs and those of the sections whose only "
                 "override is `protocol.train_images`; mean ± std over seeds, OA for one / two / three requested "
                 "types; generated scenes are free, the thesis trained on 427):", "", markdown_table(table)]
    kernels = _kernel_paths(runs)
    if kernels:
        text += ["", *kernels]
    ours = runs[runs.method == "gnn_att"]
    artifacts = {}
    if len(ours) and "geometry_blockers_within_filter" in ours:
        artifacts["geometry.png"] = (ours.iloc[0].run_id, "figures/geometry.png")
    return Section(
        "Table 6.1: object accuracy on single images", "\n".join(text), pd.DataFrame(records), figures, artifacts
    )


TRAIN_IMAGES = f"{PARAM_PREFIX}protocol.train_images"


def _training_set_sizes(runs: pd.DataFrame):
    """For the default section: (table, figure) of the OA per method over ``protocol.train_images``, from every
    finished run of the experiment in the same store whose only override (beyond the default's) is that key; the
    methods run at two sizes or more. None otherwise."""
    uri = f"{PARAM_PREFIX}logger.tracking_uri"
    if set(runs.get("variant", [])) != {DEFAULT_VARIANT} or not {uri, "experiment"} <= set(runs):
        return None
    every = fetch_runs(runs[uri].iloc[0], runs["experiment"].iloc[0], variant=None)
    if every.empty or TRAIN_IMAGES not in every:
        return None
    own = every["variant_overrides"].fillna("").astype(str).str.strip()
    sized = every[((every["variant"] == DEFAULT_VARIANT) | own.str.fullmatch(r"protocol\.train_images=\d+"))
                  & every[TRAIN_IMAGES].notna()]
    sized = sized.assign(images=pd.to_numeric(sized[TRAIN_IMAGES]), oa=_pooled(sized, "oa"))
    counts = sized.groupby("method").images.nunique()
    methods = [m for m in METHODS if counts.get(m, 0) > 1]
    if not methods:
        return None
    rows, fig = [], plt.figure(figsize=(5.5, 3.4))
    ax = fig.gca()
    for k, method in enumerate(methods):
        mine = sized[sized.method == method]
        row, points = {"method": METHODS[method]}, []
        for images, at in sorted(mine.groupby("images")):
            row[f"{int(images)} images"] = " / ".join(fmt(*spread(at, f"oa_{n}"), 3) for n in REQUEST_SIZES)
            points.append((images, *spread(at, "oa")))
        rows.append(row)
        xs, means, stds = zip(*points)
        ax.errorbar(xs, means, yerr=stds, marker="o", capsize=3, color=f"C{k}", label=METHODS[method])
    thesis = thesis_results()["ch6"]["table_6_1"]["gnn_att"]
    ax.axhline(min(ref[0] for ref in thesis[1:]), color="grey", linestyle="--", linewidth=1,
               label="thesis GNN_Att, three types (427 images)")
    ax.set_xscale("log", base=2)
    ticks = sorted(sized.images.unique())
    ax.set_xticks(ticks, [str(int(t)) for t in ticks])
    ax.minorticks_off()
    ax.set_xlabel("training images (log scale)")
    ax.set_ylabel("object accuracy, mean of 1-3 types")
    ax.legend(fontsize=6)
    fig.tight_layout()
    return pd.DataFrame(rows).fillna("–"), fig


KERNELS_BEFORE = "the machine's widest (before hrc_lab.kernels)"


def _kernel_paths(runs: pd.DataFrame) -> list[str]:
    """For the default section: how far a cell moves when only the CPU kernels change. Every finished default run
    in the same store, by its ``cpu_kernels`` tag (:mod:`hrc_lab.kernels`; runs without it predate the pinning and
    used the widest paths of their machine): for each method and seed run under two settings, the OA per request
    size under each and the cells' differences, beside the seeds' spread. Empty when no method has such a pair."""
    uri = f"{PARAM_PREFIX}logger.tracking_uri"
    if set(runs.get("variant", [])) != {DEFAULT_VARIANT} or not {uri, "experiment"} <= set(runs):
        return []
    every = finished_runs(runs[uri].iloc[0], runs["experiment"].iloc[0])
    if every.empty:
        return []
    every = every[every["variant"] == DEFAULT_VARIANT]
    every = every.assign(kernels=every.get("cpu_kernels", pd.Series(index=every.index, dtype=object))
                         .fillna(KERNELS_BEFORE))
    every = every.drop_duplicates(["method", "seed", "kernels"], keep="first")  # newest first
    cells, titles = [f"oa_{n}" for n in REQUEST_SIZES], [title for _, title in COLUMNS[1:]]
    rows, moved, paired, cell_moves = [], [], [], []
    for method in METHODS:
        mine = every[every.method == method]
        settings = list(dict.fromkeys(mine.kernels))
        if len(settings) < 2:
            continue
        new, old = settings[0], settings[1]  # the newest setting, and the one before it
        seeds = sorted(set(mine[mine.kernels == new].seed) & set(mine[mine.kernels == old].seed))
        if not seeds:
            continue
        runs_of = {k: mine[(mine.kernels == k) & mine.seed.isin(seeds)].set_index("seed").sort_index()
                   for k in (new, old)}
        paired += [runs_of[new], runs_of[old]]
        for k in (new, old):
            rows.append({"method": METHODS[method], "kernels": k, "seeds": ", ".join(map(str, seeds)),
                         **{title: fmt(*spread(runs_of[k], c), 3) for c, title in zip(cells, titles)},
                         "detector recall": fmt(*spread(runs_of[k], "detector_recall"), 3)})
        moves = []  # per table cell: |mean over seeds, new - old| and the larger seed std (hrc-lab-reproduce --check)
        for c in cells:
            (m_new, s_new), (m_old, s_old) = spread(runs_of[new], c), spread(runs_of[old], c)
            moves.append((abs(m_new - m_old), max(s_new, s_old)))
        cell_moves += moves
        delta = (runs_of[new][cells] - runs_of[old][cells]).abs().to_numpy().ravel()
        seed_std = max(std for _, std in moves)
        moved.append(f"{METHODS[method]}: the {len(delta)} cells (seed x request size) moved by {delta.mean():.3f} "
                     f"on average, at most {delta.max():.3f}; the seeds' largest std in a column is {seed_std:.3f}")
    if not rows:
        return []
    both = pd.concat(paired)
    machines = ", ".join(sorted(set(both.get("cpu", pd.Series(dtype=object)).dropna()))) or "machines not logged"
    widest = ", ".join(sorted(set(both.loc[both.kernels == KERNELS_BEFORE].get("cpu_capability",
                                                                              pd.Series(dtype=object)).dropna())))
    return ["Other CPU kernels, same cells: the methods run under two kernel settings (tag `cpu_kernels`; since "
            "`hrc_lab.kernels` oneDNN, MKL and ATen are pinned to AVX2, the paths an AVX2-only CPU takes, so that "
            "a network can train to the same weights on other CPUs; runs without the tag predate the pinning and took "
            f"the widest paths of their CPU{f', here {widest}' if widest else ''}), same config and seeds, on "
            f"{machines}. The differences are what a change of kernel paths does to a cell, i.e. how far a cell "
            "moved between two CPUs before the pinning "
            "([which paths change the detector's weights](ch6_grasp/cpu_kernels.md), `scripts/cpu_kernel_paths.py`). "
            "The detector is trained once for every seed of a run (`grasp.detector.seed`), so the seeds' spread "
            "leaves its training out; other kernels retrain it, as a new detector seed would. The table above reads "
            "each method's newest runs, the first setting of its pair:", "",
            markdown_table(pd.DataFrame(rows)), "", *(f"- {line}." for line in moved), "",
            f"Of the {len(cell_moves)} cells of the table (a method's mean over seeds at one request size), "
            f"{sum(d > s for d, s in cell_moves)} moved by more than the larger of their two seed stds (the "
            f"criterion of `hrc-lab-reproduce --check`); the means moved by "
            f"{sum(d for d, _ in cell_moves) / len(cell_moves):.3f} on average, at most "
            f"{max(d for d, _ in cell_moves):.3f}."]


def _pooled(runs: pd.DataFrame, stem: str) -> pd.Series:
    """Per run, the mean of ``<stem>_1..3`` (the three request sizes, each over its own test requests)."""
    columns = [f"{stem}_{k}" for k in REQUEST_SIZES if f"{stem}_{k}" in runs]
    return runs[columns].mean(axis=1) if columns else pd.Series(float("nan"), index=runs.index)


def _decomposition(runs: pd.DataFrame, methods: list[str], part_a_thesis: float) -> list[str]:
    """Where each method's object accuracy is lost: requested parts the detector misses (training and test),
    graspability on the parts it finds, and the object accuracy per requested part type."""
    if "train_detected" not in runs:
        return []  # runs older than the diagnostics
    runs = runs.assign(test_detected=_pooled(runs, "detected"), test_fit=_pooled(runs, "fit_acc"),
                       test_oa=_pooled(runs, "oa"))
    columns = [("train_detected", "train: requested parts detected"),
               ("train_part_grasp_acc", "train: graspability, every requested part"),
               ("test_detected", "test: requested parts detected"),
               ("test_fit", "test: graspability on detected parts"), ("test_oa", "test: OA (1-3 types)")]
    columns += [(c, f"test: OA of part {c[len('oa_type_'):]}") for c in sorted(runs.columns)
                if c.startswith("oa_type_")]
    rows = []
    for method in methods:
        part = runs[runs.method == method]
        rows.append({"method": METHODS[method]} | {title: fmt(*spread(part, metric), 3) for metric, title in columns})
    return [
        f"Where the object accuracy is lost ({over_seeds(runs, listed=False)}; test columns pooled over the three "
        "request sizes). An undetected requested part counts as wrong, so the detected share bounds the OA; the "
        "graspability on detected parts is the solver's own accuracy. Per part type: the thesis finds part a the "
        f"hardest request, OA about {part_a_thesis} (Sec. 6.4.1).",
        "",
        markdown_table(pd.DataFrame(rows)),
        "",
    ]


def _geometry(runs: pd.DataFrame, text: dict) -> list[str]:
    """The test scenes' geometry in Eq. 6.1's units (the same scenes for every method: read from one run)."""
    if "geometry_blockers_within_filter" not in runs:
        return []
    one = runs.iloc[0]
    filter_ = text["distance_filter_threshold"]
    low, high = sorted(text["fig_6_3_pair_distances"])
    return [
        f"The test scenes measured against the {filter_} distance filter (ground-truth boxes; distances are "
        "box-centre distances over the image side, the unit of Eq. 6.1 and of the filter). Of the pairs in which "
        f"one part blocks the other, {one.geometry_blockers_within_filter:.0%} lie within {filter_} (median "
        f"{one.geometry_blocker_distance_median:.3f}, largest {one.geometry_blocker_distance_max:.3f}), so "
        f"GNN_DF_Att's graph keeps that share of the edges a solution depends on; of all pairs "
        f"{one.geometry_pairs_within_filter:.0%} lie within it (median {one.geometry_pair_distance_median:.3f}), "
        f"and a part has {one.geometry_neighbours_within_filter:.2f} neighbours within it on average. Eq. 6.1 "
        f"gives a blocker {one.geometry_blocker_weight_ratio:.2f}× the uniform weight 1/(n−1) on average. The "
        f"thesis' Fig. 6.3 shows touching a-b pairs {low:.2f} and {high:.2f} apart. geometry.png shows the "
        "distances of the blocking pairs beside those of all pairs.",
        "",
    ]


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
    ax.set_ylabel("train graspability accuracy")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


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
            ref = thesis_value(thesis["single_image"], thesis["columns"], count)  # None: a count it did not run
            row[f"{count} objects"] = fmt(mean, std, 3) + (f" ({'–' if ref is None else ref})"
                                                           if method == "gnn_att" else "")
            records.append({"method": method, "objects": count, "mean": mean, "std": std})
        rows.append(row)
    text = [
        "Algorithm 4 on one image: for a random requested part type, the solver checks the requested parts; when "
        "none is graspable, the decoded solution's part types (nearest detected part of each) become the new "
        "request, until a graspable part or help. Right when the final grasp is a part the labelling rule finds "
        "graspable among the requested parts (or, if none is, among those the rule's own iteration reaches), or "
        f"when both end in help. {over_seeds(runs, start=True)}; thesis (single image, 10 "
        "cases per count, checked by hand) in brackets. The robot row (the same scenes and requests, acted on "
        "in the robosuite cell) is in [ch6_robot.md](ch6_robot.md) (`hrc-lab-report ch6_robot`).",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    ours = runs[runs.method == "gnn_att"]
    text += _failures(ours, counts, over_seeds(runs, listed=False)) + _answer_lengths(ours)
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


@register_section("table_6_3")
def table_6_3(runs: pd.DataFrame) -> Section:
    thesis, facts = thesis_results()["ch6"]["table_6_3"], thesis_results()["ch6"]["text"]
    counts = sorted(int(c[len("ia_") :]) for c in runs.columns if c.startswith("ia_") and c[len("ia_") :].isdigit())
    rows, records = [], []
    for method in [m for m in METHODS if m in set(runs.method)]:
        ours = runs[runs.method == method]
        row = {"method": METHODS[method], "IA": fmt(*spread(ours, "ia"), 3),
               "thesis IA (VMRD v2)": str(thesis.get(method, "–"))}
        row |= {f"IA, {n} objects": fmt(*spread(ours, f"ia_{n}"), 3) for n in counts}
        row["object accuracy"] = fmt(*spread(ours, "oa"), 3)
        rows.append(row)
        records.append({"method": method, "metric": "ia", "mean": spread(ours, "ia")[0]})
    written = bool(runs["written_by_hrc_lab"].min()) if "written_by_hrc_lab" in runs else True
    source = (f"our {amount(runs, 'protocol.train_images', 'trainval')} and "
              f"{amount(runs, 'protocol.test_images', 'test')} rendered clutter scenes (Table 6.1's) written in "
              "VMRD v2's layout and read back through the same loader (`hrc_lab/data/vmrd.py`), the rule's blockers "
              "as each part's children" if written else f"the data set at `{setting(runs, 'env.vmrd_root')}`")
    text = [
        "Image-based accuracy (IA, 6.4.2): a test image counts when every object in it is right: detected, its "
        "graspability right and, when it cannot be grasped, its decoded solution right (every object of the image "
        f"is requested). Data: {source}. {over_seeds(runs, start=True)}. VMRN classifies every ordered pair of "
        "detected objects as parent / child / none from the box features of both and of their union box "
        "(`hrc_lab/grasp/vmrn.py`); an object with predicted children is not graspable and its solution names "
        "their types (help when one has its own). The thesis ran VMRD v2 "
        f"({facts['vmrd_object_types_in_test']} daily-life classes, up to {facts['vmrd_max_objects_per_image']} "
        "objects per image); "
        + ("these machines cannot download it, so the numbers are not comparable with the thesis' column beside "
           "them: the protocol is the thesis', the data are ours." if written else
           f"these runs read {_classes(runs)} classes from the data set's annotations (the detector's classes, the "
           f"label one-hots and the solution words), its images letterboxed to {keyed(runs, 'env.image_size', 'px')} "
           "square."),
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    if counts:
        text += ["", f"An image counts only when all of its objects are right, so IA falls with the object count "
                     f"(columns): our test images hold {counts[0]}–{counts[-1]} parts, VMRD's at most "
                     f"{facts['vmrd_max_objects_per_image']} objects."]
    return Section("Table 6.3: image-based accuracy " + ("(our scenes in VMRD's layout)" if written else
                                                        "(a data set in VMRD's layout)"), "\n".join(text),
                   pd.DataFrame(records))


TYPES_METRIC = re.compile(r"types(\d+)_grasp_ia")  # Fig. 6.9's runs log types<k>_<name> per number of types k
STAGES = (("grasp_ia", "GNN: graspability"), ("solution_ia", "LSTM_Att: solutions"))


@register_section("fig_6_9")
def fig_6_9(runs: pd.DataFrame) -> Section:
    """Fig. 6.9: the image-based accuracy of the graspability classification and of the decoded solutions per number
    of object types k (``types<k>_*`` metrics of :func:`hrc_lab.experiments.ch6_grasp.fig_6_9`)."""
    counts = sorted(int(m.group(1)) for c in runs.columns if (m := TYPES_METRIC.fullmatch(c)))
    methods = ", ".join(METHODS.get(m, m) for m in sorted(set(runs.method)))
    rows, records = [], []
    for k in counts:
        row = {"object types": k, "test images": fmt(spread(runs, f"types{k}_test_images")[0], None, 0),
               "objects per image": fmt(spread(runs, f"types{k}_objects")[0], None, 2)}
        for stage, title in STAGES:
            mean, std = spread(runs, f"types{k}_{stage}")
            row[f"{title} IA"] = fmt(mean, std, 3)
            records.append({"types": k, "stage": stage, "mean": mean, "std": std})
        row["IA (Table 6.3's)"] = fmt(*spread(runs, f"types{k}_ia"), 3)
        row["train graspability"] = fmt(*spread(runs, f"types{k}_train_grasp_acc"), 3)
        rows.append(row)
    facts = thesis_results()["ch6"]["text"]
    text = [
        f"{methods} trained and tested on data sets of k object types, each image's every object requested. GNN: "
        "the share of test images whose every object is detected with the right graspability; LSTM_Att: over the "
        "test images holding an object that cannot be grasped, the share whose every such object is detected and "
        "decoded to the right solution. " + _type_data(runs) + f" {over_seeds(runs, start=True)}.",
        "",
        f"Thesis (Fig. 6.9, VMRD, up to {facts['vmrd_object_types_in_test']} types; a figure without stated values): "
        "as the number of object types grows the GNN's accuracy \"does not decrease a lot while the LSTM_Att's "
        "performance drops\", the decoder naming wrong objects.",
        "",
        markdown_table(pd.DataFrame(rows)) if rows else "(no runs)",
        *_equal_counts(runs, counts),
    ]
    figures = {"fig_6_9.png": _stages_figure(pd.DataFrame(records), methods)} if records else {}
    return Section("Fig. 6.9: graspability and solutions over the number of object types", "\n".join(text),
                   pd.DataFrame(records), figures)


def _type_data(runs: pd.DataFrame) -> str:
    """Where Fig. 6.9's data sets of k types come from."""
    written = bool(runs["written_by_hrc_lab"].min()) if "written_by_hrc_lab" in runs else True
    if not written:
        return (f"Data: the images of `{setting(runs, 'env.vmrd_root')}` whose objects are all of its k most frequent "
                "training classes; one detector, trained on every image, reads them all.")
    return ("Data: our clutter scenes with only the k part types of the largest `env.max_counts` (a, then b, then c; "
            "the others' counts 0), rendered for each k (as many training and test scenes as Table 6.3: "
            f"{amount(runs, 'protocol.train_images', 'trainval')}, {amount(runs, 'protocol.test_images', 'test')}) "
            "and written in VMRD's layout; Table 6.3's detector (all three types) reads them all. Our env has three "
            "part types, so k stops at 3, and a scene of part a alone holds 3 parts (`env.max_counts`), so k also "
            "changes the object count (images of equal count are compared below).")


def _equal_counts(runs: pd.DataFrame, counts: list[int]) -> list[str]:
    """Both stages per k on the images of the one object count that every k has (``types<k>_<stage>_n<n>``)."""
    present = [{int(c.rsplit("_n", 1)[1]) for c in runs.columns if c.startswith(f"types{k}_grasp_ia_n")}
               for k in counts]
    shared = sorted(set.intersection(*present)) if present else []
    if not shared:
        return []
    n = shared[0]
    rows = [{"object types": k} | {f"{title} IA": fmt(*spread(runs, f"types{k}_{stage}_n{n}"), 3)
                                   for stage, title in STAGES} for k in counts]
    return ["", f"On the test images of {n} objects only (a count every k has):", "",
            markdown_table(pd.DataFrame(rows))]


def _stages_figure(frame: pd.DataFrame, methods: str):
    """Fig. 6.9's plot: each stage's image-based accuracy over the number of object types, mean ± std over seeds."""
    fig, ax = plt.subplots(figsize=(5, 3.2))
    for stage, title in STAGES:
        part = frame[frame.stage == stage]
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


def _classes(runs: pd.DataFrame) -> str:
    """How many classes the runs' data set has ("31"), from their ``classes`` metric."""
    counts = sorted({int(n) for n in runs["classes"].dropna()}) if "classes" in runs else []
    return " or ".join(map(str, counts)) if counts else "its"


def _failures(runs: pd.DataFrame, counts: list[int], seeds: str) -> list[str]:
    """The share of cases per failure cause and part count (:func:`hrc_lab.grasp.diagnostics.failure_cause`);
    ``seeds``: what the spread is over, in words (:func:`hrc_lab.report.runs.over_seeds` of the section's runs)."""
    if not counts or f"fail_{FAILURE_CAUSES[0]}_{counts[0]}" not in runs:
        return []  # runs older than the failure causes
    rows = [{"wrong because": cause} | {f"{count} objects": fmt(*spread(runs, f"fail_{cause}_{count}"), 3)
                                        for count in counts} for cause in FAILURE_CAUSES]
    return [
        "",
        f"Why answers are wrong (GNN_Att; share of all cases per part count, {seeds}; the first cause "
        "that applies): *detection*: a part of the requested type, or one the rule's iteration from it passes "
        "through, is not detected, or a detection of the requested type matches no part; *graspability*: at some "
        "request the solver's graspability of a requested part differs from the rule's; *solution*: a decoded "
        "solution differs from the rule's; *other*: every step agrees with the rule (the nearest part of a named "
        "type is not the rule's choice, or the iteration limit).",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]


def _answer_lengths(runs: pd.DataFrame) -> list[str]:
    """How many requests Algorithm 4 made per answer, per part count, from the runs' ``table_6_2_single`` tables."""
    cases = run_tables(runs, "table_6_2_single")
    if cases.empty:
        return []
    columns = {"cases (all seeds)": ("correct", "size"), "solver: requests per answer": ("iterations", "mean"),
               "solver: answered at the first request": ("iterations", lambda n: (n == 1).mean()),
               "solver: help": ("help", "mean")}
    if "rule_requests" in cases:  # runs older than the rule's chain length lack it
        columns |= {"rule: requests needed": ("rule_requests", "mean"),
                    "rule: one request is enough": ("rule_requests", lambda n: (n == 1).mean())}
    lengths = cases.groupby("objects").agg(**columns)
    return ["", "How long the answers are (GNN_Att, all seeds; the rule's own Algorithm 4 from the goal part that "
                "needs the fewest requests): where one request is enough, the case scores the solver's first "
                "graspability check, whatever the part count.", "",
            lengths.round(3).reset_index().to_markdown(index=False)]


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch6_grasp",
    title="Ch.6 iterative visual grasping: graspability and grasp solutions from detector features",
    note="Scenes are rendered in MuJoCo (parts a, b, c dropped with physics), labelled by one geometric rule, "
         "not photos labelled by an expert; the detector is a small Faster R-CNN trained from scratch.",
    studies=(Study("ch6/table_6_1"), Study("ch6/table_6_2_single"), Study("ch6/table_6_3"),
             Study("ch6/fig_6_9")),
)
