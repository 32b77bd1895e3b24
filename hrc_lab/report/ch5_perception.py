"""Report sections of the Ch.5 perception experiments: Fig. 5.5 / 5.6 (action detector vs. baselines) and Table 5.2
end to end (generated sessions through tracking, detector and planner)."""

from __future__ import annotations

import pandas as pd
from matplotlib.figure import Figure

from hrc_lab.report.plan import Plan, Study
from hrc_lab.report.runs import amount, over_seeds, setting, setting_number, spread
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, markdown_table, thesis_cells, thesis_fmt, thesis_results

METHODS = {
    "hand_lstm_fcn": "Ours: MediaPipe + LSTM-FCN + VGG-style CNN",
    "cnn_lstm": "CNN+LSTM (plain LSTM on the track)",
    "hand_cnn": "Hand-centric CNN (crop only)",
    "cnn_lstm_video": "CNN-LSTM on frames [146]",
}
CELLS = ["1goal", "2goals", "3goals"]


@register_section("fig_5_6")
def fig_5_6(runs: pd.DataFrame) -> Section:
    text_ref = thesis_results()["ch5"]["text"]
    methods = [m for m in METHODS if m in set(runs.method)]
    rows, records = [], []
    for method in methods:
        part = runs[runs.method == method]
        row = {"method": METHODS[method], "seeds": len(part)}
        for metric, title in (("train_acc", "train"), ("test_acc", "test"), ("all_acc", "all clips (Fig. 5.5)")):
            mean, std = spread(part, metric)
            row[title] = fmt(mean, std, 3)
            records.append({"method": method, "metric": metric, "mean": mean, "std": std})
        row["classify ms"] = fmt(*spread(part, "classify_ms"), 1)
        rows.append(row)
    ours = runs[runs.method == "hand_lstm_fcn"]
    window = amount(runs, "env.video.window", "frames")
    frames, fps = setting_number(runs, "env.video.window"), setting_number(runs, "env.video.fps")
    duration = f", over its {frames / fps:g} s" if frames and fps else ""
    latency = ""
    if len(ours):
        latency = (
            f"Latency on this CPU (ours): MediaPipe tracking {fmt(*spread(ours, 'tracking_ms_per_frame'), 1)} ms per "
            f"frame, classification {fmt(*spread(ours, 'classify_ms'), 1)} ms per window, so "
            f"{fmt(*spread(ours, 'latency_window_ms'), 0)} ms from a window's last frame to its action "
            f"(thesis: {text_ref['detection_latency_ms']} ms average detection time, GPU); tracking every frame of a "
            f"window ({window}) costs {fmt(*spread(ours, 'latency_window_total_ms'), 0)} ms in total{duration}."
        )
    n_clips = runs.n_train.iloc[0] + runs.n_test.iloc[0]
    train = setting_number(runs, "protocol.train_fraction")
    split = (f"{train:g} / {1 - train:g} train / test split" if train is not None
             else f"train / test split (`protocol.train_fraction` {setting(runs, 'protocol.train_fraction')})")
    text = [
        f"Action accuracy on generated clips of the 18 actions of Table 5.1 ({int(n_clips)} clips of {window}, "
        f"MediaPipe found the hand in {runs.tracked_fraction.mean():.1%} of their frames), {split} per "
        f"action; {over_seeds(runs)} (each seed: a new split and initialisation). "
        "The thesis gives Fig. 5.6 only as bars (ours best, hand-centric CNN and CNN-LSTM clearly lower) and "
        f"{text_ref['detector_accuracy_whole_video']:.1%} for its detector over the whole video set (Fig. 5.5).",
        "",
        markdown_table(pd.DataFrame(rows)),
        "",
        latency,
    ]
    artifacts = {}
    if len(ours):
        artifacts["confusion_hand_lstm_fcn.png"] = (ours.sort_values("seed").iloc[0].run_id, "figures/confusion.png")
    frame = pd.DataFrame(records)
    return Section("Fig. 5.5 / 5.6: action detector vs. baselines", "\n".join(text), frame,
                   {"fig_5_6.png": _bars(frame)}, artifacts)


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


@register_section("table_5_2")
def table_5_2(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch5"]["table_5_2"]
    rows, records = [], []
    for cell in thesis_cells(runs.cell, CELLS):
        part = runs[runs.cell == cell]
        goals = int(cell.split("goal")[0])  # "1goal", "3goals", a user's "10goals"
        ref = thesis.get(f"goals_{goals}", [(None, None)] * 3)  # the thesis' AD, SG, SC; None: a count not run
        row = {"goals": goals, "seeds": len(part), "sessions": int(part.n_sessions.sum())}
        for (metric, title), (ref_mean, ref_std) in zip((("ad_acc", "AD %"), ("sg_acc", "SG %"), ("sc_acc", "SC %")),
                                                        ref):
            mean, std = (100 * v for v in spread(part, metric))
            row[title] = f"{fmt(mean, std, 1)} ({thesis_fmt(ref_mean, ref_std, 1)})"
            records.append({"goals": goals, "metric": metric, "mean": mean, "std": std})
        for metric, title in (("sg_acc_determined", "SG % determined"), ("sc_acc_determined", "SC % determined"),
                              ("sc_determined_share", "SC events determined %")):
            mean, std = (100 * v for v in spread(part, metric))
            row[title] = fmt(mean, std, 1)
            records.append({"goals": goals, "metric": metric, "mean": mean, "std": std})
        row["fast sessions"] = int(part.n_fast_sessions.sum())
        for metric, title in (("ad_acc_fast", "AD % fast"), ("sg_acc_fast", "SG % fast"), ("sc_acc_fast", "SC % fast")):
            mean, std = (100 * v for v in spread(part, metric))
            row[title] = fmt(mean, std, 1)
            records.append({"goals": goals, "metric": metric, "mean": mean, "std": std})
        rows.append(row)
    text = [
        "Generated assembly sessions streamed frame by frame through MediaPipe tracking, the action detector "
        "(`hand_lstm_fcn`, trained once on all generated clips, "
        f"{amount(runs, 'protocol.clips_per_class', 'per action')}) and the semantic planner's Algorithm 3 loop. AD: "
        f"share of windows ({amount(runs, 'env.video.window', 'frames')}) whose action is the majority true label "
        "of their frames; SG: the Semantic Guidance "
        "on screen after each human placement (hand out of view) is right for every part type; SC: the first robot "
        "command during each screw is the expert's next part and positions. *Determined*: the events whose right "
        "answer the true assembly so far fixes; at the others another goal assembles the same parts there and "
        "wants something else, so no planner that sees the assembly can be sure (the thesis: \"a part can occupy "
        "the same assembly position\" in different goals, 5.4.3); the last column is their share of the screws. "
        f"{over_seeds(runs, start=True)} (per seed the sessions are new); thesis (20 real experiments x 5) in "
        "brackets. Fast sessions play every action about twice as fast with motion blur, the thesis' stated "
        "failure case.",
        "",
        markdown_table(pd.DataFrame(rows)),
        "",
        f"Latency on this CPU: MediaPipe {fmt(*spread(runs, 'tracking_ms_per_frame'), 1)} ms per frame, detector "
        f"{fmt(*spread(runs, 'classify_ms'), 1)} ms per window.",
    ]
    first = runs.sort_values(["cell", "seed"]).iloc[0]
    artifacts = {"session_strip.png": (first.run_id, "figures/session_strip.png"),
                 "session_annotated.mp4": (first.run_id, "videos/session_annotated.mp4")}
    return Section("Table 5.2 end to end: video -> actions -> plans", "\n".join(text), pd.DataFrame(records), {},
                   artifacts)


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch5_perception",
    title="Ch.5 hand-centric action detector and the video-to-plan pipeline",
    note="Videos are generated: a top-down view of our assembly cell with an OpenCV-drawn hand that MediaPipe "
         "tracks, not RealSense recordings of a worker; every network trains from scratch on the CPU.",
    studies=(Study("ch5/fig_5_6"), Study("ch5/table_5_2")),
)
