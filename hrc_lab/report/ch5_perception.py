"""Report sections of the Ch.5 perception experiments: Fig. 5.5 / 5.6 (action detector vs. baselines) and Table 5.2
end to end (generated sessions through tracking, detector and planner)."""

from __future__ import annotations

import pandas as pd
from matplotlib.figure import Figure

from hrc_lab.report.ch5_planner import SC, SG, table_5_2_rows
from hrc_lab.report.headline import results_frame
from hrc_lab.report.plan import Pick, Plan, Row, Study
from hrc_lab.report.runs import amount, over_seeds, setting, setting_number, spread
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, markdown_table, thesis_cells, thesis_results

METHODS = {
    "hand_lstm_fcn": "Ours: MediaPipe + LSTM-FCN + VGG-style CNN",
    "cnn_lstm": "CNN+LSTM (plain LSTM on the track)",
    "hand_cnn": "Hand-centric CNN (crop only)",
    "cnn_lstm_video": "CNN-LSTM on frames [146]",
}
SHORT = {"hand_lstm_fcn": "ours", "cnn_lstm": "CNN+LSTM", "hand_cnn": "hand-centric CNN", "cnn_lstm_video": "CNN-LSTM"}
OURS = "hand_lstm_fcn"
RANKING = "ranking"  # the results' row of Fig. 5.6's statement
CELLS = ["1goal", "2goals", "3goals"]
AD = "action_detector"  # Table 5.2's first column (thesis_results.yaml ch5.table_5_2.columns)
FIG_5_6_METRICS = ("train_acc", "test_acc", "all_acc", "tracked_fraction", "tracking_ms_per_frame", "classify_ms",
                   "latency_window_ms", "latency_window_total_ms")


def ranking(records: pd.DataFrame) -> dict:
    """Fig. 5.6's statement (ours better than the baselines) on our test accuracies: the methods' means, best first,
    and whether ours is the best (``n``: our seeds)."""
    test = records[records.metric == "test_acc"].sort_values("mean", ascending=False)
    if len(test) < 2 or OURS not in set(test.method):
        return {"row": RANKING, "column": "", "text": "", "met": None}
    text = "test: " + ", ".join(f"{SHORT.get(m, m)} {v:.2f}" for m, v in zip(test.method, test["mean"]))
    seeds = int(test[test.method == OURS].n.iloc[0])
    return {"row": RANKING, "column": "", "n": seeds, "text": text, "met": bool(test.method.iloc[0] == OURS)}


@register_section("fig_5_6")
def fig_5_6(runs: pd.DataFrame) -> Section:
    methods = [m for m in METHODS if m in set(runs.method)] + sorted(set(runs.method) - set(METHODS))
    rows, records = [], []
    for method in methods:
        part = runs[runs.method == method]
        row = {"method": METHODS.get(method, method), "seeds": len(part)}
        for metric in FIG_5_6_METRICS:
            mean, std = spread(part, metric)
            records.append({"method": method, "metric": metric, "mean": mean, "std": std, "n": len(part)})
        for metric, title in (("train_acc", "train"), ("test_acc", "test"), ("all_acc", "all clips (Fig. 5.5)")):
            row[title] = fmt(*spread(part, metric), 3)
        row["ms per window"] = fmt(*spread(part, "latency_window_ms"), 1)
        rows.append(row)
    frame = pd.DataFrame(records)
    train = setting_number(runs, "protocol.train_fraction")
    split = (f"{train:g} / {1 - train:g} train / test split" if train is not None
             else f"train / test split (`protocol.train_fraction` {setting(runs, 'protocol.train_fraction')})")
    n_clips = int(runs.n_train.iloc[0] + runs.n_test.iloc[0])
    text = [
        f"Action accuracy on {n_clips} generated clips of the actions of Table 5.1 "
        f"({amount(runs, 'protocol.clips_per_class', 'per action')}, {amount(runs, 'env.video.window', 'frames')}; "
        f"MediaPipe found the hand in {runs.tracked_fraction.mean():.1%} of their frames), {split} per action; "
        f"{over_seeds(runs)} (each seed a new split and initialisation). ms per window: tracking its last frame and "
        f"classifying, on this CPU (thesis: {thesis_results()['ch5']['text']['detection_latency_ms']} ms, GPU).",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    ours = runs[runs.method == OURS]
    results = [ranking(frame)]
    artifacts = {}
    if len(ours):
        mean, std = spread(ours, "all_acc")
        results.append({"row": OURS, "column": "", "mean": mean, "std": std, "n": len(ours)})
        artifacts["confusion_hand_lstm_fcn.png"] = (ours.sort_values("seed").iloc[0].run_id, "figures/confusion.png")
    return Section("Fig. 5.5 / 5.6: action detector vs. baselines", "\n".join(text), frame,
                   {"fig_5_6.png": _bars(frame)}, artifacts, results=results_frame(results))


def _bars(frame: pd.DataFrame) -> Figure:
    fig = Figure(figsize=(7, 3.4))
    ax = fig.subplots()
    methods = list(dict.fromkeys(frame.method))
    for i, metric in enumerate(("train_acc", "test_acc")):
        part = frame[frame.metric == metric].set_index("method").reindex(methods)
        ax.bar([j + 0.4 * i for j in range(len(methods))], part["mean"], 0.4, yerr=part["std"], capsize=3,
               label=metric.replace("_acc", ""))
    ax.set_xticks([j + 0.2 for j in range(len(methods))], [m.replace("_", "\n") for m in methods], fontsize=8)
    ax.set_ylabel("accuracy")
    ax.set_ylim(0, 1.05)
    ax.grid(axis="y", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    return fig


# Table 5.2's metrics (percent): ours of the thesis' columns, then the shown and CSV-only ones; latencies in ms
TABLE_5_2_METRICS = {"ad_acc": AD, "sg_acc": SG, "sc_acc": SC}
TABLE_5_2_SHOWN = {"ad_acc": "AD %", "sg_acc": "SG %", "sc_acc": "SC %", "sc_acc_determined": "SC % determined",
                   "ad_acc_fast": "AD % fast", "sc_acc_fast": "SC % fast"}
TABLE_5_2_CSV = ("sg_acc_determined", "sc_determined_share", "sg_acc_fast")
LATENCIES = ("tracking_ms_per_frame", "classify_ms")


@register_section("table_5_2")
def table_5_2(runs: pd.DataFrame) -> Section:
    rows, records, csv = [], [], []
    for cell in thesis_cells(runs.cell, CELLS):
        part = runs[runs.cell == cell]
        row = {"goals": int(cell.split("goal")[0]), "sessions": int(part.n_sessions.sum())}  # "3goals", "10goals"
        for metric in (*TABLE_5_2_SHOWN, *TABLE_5_2_CSV, *LATENCIES):
            mean, std = (v * (1 if metric in LATENCIES else 100) for v in spread(part, metric))
            csv.append({"cell": cell, "metric": metric, "mean": mean, "std": std, "seeds": len(part)})
            if metric in TABLE_5_2_SHOWN:
                row[TABLE_5_2_SHOWN[metric]] = fmt(mean, std, 1)
            if metric in TABLE_5_2_METRICS:
                records.append({"row": cell, "column": TABLE_5_2_METRICS[metric], "mean": mean, "std": std,
                                "n": int(part[metric].notna().sum())})
        rows.append(row)
    text = [
        f"Generated sessions streamed frame by frame through MediaPipe, the action detector (trained once on "
        f"{amount(runs, 'protocol.clips_per_class', 'clips per action')}) and the Algorithm 3 loop. AD: windows whose "
        "action is right; SG: the guidance after each human placement, right for every part type; SC: the robot "
        "command at each screw; determined: the screws whose answer the assembly so far fixes. Fast: actions ~2× "
        f"faster, blurred (the thesis' failure case). {over_seeds(runs, start=True)}; new sessions per seed.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    first = runs.sort_values(["cell", "seed"]).iloc[0]
    artifacts = {"session_strip.png": (first.run_id, "figures/session_strip.png"),
                 "session_annotated.mp4": (first.run_id, "videos/session_annotated.mp4")}
    return Section("Table 5.2 end to end: video -> actions -> plans", "\n".join(text), pd.DataFrame(csv), {},
                   artifacts, results=results_frame(records))


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch5_perception",
    title="Ch.5 hand-centric action detector and the video-to-plan pipeline",
    note="Videos are generated: a top-down view of our assembly cell with an OpenCV-drawn hand that MediaPipe "
         "tracks, not RealSense recordings of a worker; every network trains from scratch on the CPU.",
    studies=(
        Study("ch5/fig_5_6"),
        Study("ch5/table_5_2"),
        Study("ch5/fig_5_6", ("perception=hand_lstm_fcn", "protocol.clips_per_class=96"), key="detector_clips",
              title="Fig. 5.5 / 5.6, ours on the session experiments' larger clip set",
              question="Is our accuracy over all clips below the thesis' because Fig. 5.6 has few generated clips "
                       "per action?"),
    ),
    rows=(
        Row("Fig. 5.5", "Action detector, whole video set", "ch5.text.detector_accuracy_whole_video",
            Pick("fig_5_6", OURS), why="few generated clips per action, from scratch ([more clips](#detector_clips))"),
        Row("Fig. 5.6", "Ours vs CNN+LSTM, hand-centric CNN, CNN-LSTM", "", Pick("fig_5_6", RANKING),
            claim="\"the proposed method demonstrates better performance\" (5.4.1)"),
        *table_5_2_rows("Table 5.2 (end to end: video -> actions -> plans)", "table_5_2",
                        {1: "our detector on windows of generated sessions ([on clips](#detector_clips))"}),
    ),
)
