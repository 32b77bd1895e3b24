"""Report sections of the demonstration jobs: the scripted expert's success rate per scenario, its speed, and the
agreement of the change-point stage segmentation with the expert's labels; beside them the rendered demonstration of
each scenario the plan films (``data/render_demo``, published to ``reports/videos/``)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from hrc_lab.report.plan import Plan, Study  # noqa: E402
from hrc_lab.report.runs import amount, keyed  # noqa: E402
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, thesis_results  # noqa: E402

COLUMNS = {
    "expert_success_rate": "expert SR",
    "n_demos": "demos",
    "steps_per_object": "steps / object",
    "segmentation_agreement": "stage agreement",
    "env_steps_per_s": "env steps/s",
    "demos_per_min": "demos/min",
}
# the scenarios the plan renders (scenario -> data/render_demo's overrides); each video is reports/videos/<scenario>
VIDEOS = {
    "4of5": ("env=package_to_order_4of5",),
    "3of5_case2": ("env=package_to_order_3of5", "env.sim.case=2"),
    "one_object_case1": ("env=error_correction_one_object_case1",),
    "two_object_case2": ("env=error_correction_two_object_case2",),
}


def _table(runs: pd.DataFrame) -> pd.DataFrame:
    frame = runs.sort_values("scenario")
    table = pd.DataFrame({"scenario": frame.scenario, "seed": frame.seed})
    for metric, title in COLUMNS.items():
        digits = 0 if metric in ("n_demos", "env_steps_per_s") else 2
        table[title] = [fmt(v, digits=digits) for v in frame[metric]]
    return table


def _section(runs: pd.DataFrame, title: str, what: str) -> Section:
    table = _table(runs)
    videos = [scenario for scenario in VIDEOS if scenario in set(runs.scenario)]
    text = "\n".join([
        f"{amount(runs, 'protocol.episodes', 'scripted-expert episodes')} per {what}. Expert SR: every object within "
        f"δr {keyed(runs, 'env.sim.success_threshold', 'm')} of its goal, released, no collision (Eq. 4.7). Stage "
        "agreement: steps whose PELT change-point stage is the expert's label. Speeds: wall-clock, without "
        "rendering, beside the sweep's other jobs.",
        "",
        table.to_markdown(index=False, disable_numparse=True),
        "",
        *(f"![{scenario}](videos/{scenario}_strip.jpg) [{scenario}.mp4](videos/{scenario}.mp4)" for scenario in videos),
    ])
    return Section(title, text, table, {f"{runs.table.iloc[0]}.png": _plot(runs)})


def _plot(runs: pd.DataFrame):
    frame = runs.sort_values("scenario")
    fig, ax = plt.subplots(figsize=(6.5, 3.2))
    x = range(len(frame))
    ax.bar([i - 0.2 for i in x], frame.expert_success_rate, width=0.4, label="expert success rate")
    ax.bar([i + 0.2 for i in x], frame.segmentation_agreement, width=0.4, label="stage agreement")
    ax.set_xticks(list(x), frame.scenario, rotation=30, ha="right", fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return fig


@register_section("collect_ch4")
def collect_ch4(runs: pd.DataFrame) -> Section:
    return _section(runs, "Package-to-order demonstrations (Ch.4)",
                    "n-of-m order and case (CASE 2: a simulated human packs a random subset first)")


@register_section("collect_ch3")
def collect_ch3(runs: pd.DataFrame) -> Section:
    teleoperated = thesis_results()["ch3"]["text"]["demos_per_case"]
    return _section(runs, "Error-correction demonstrations (Ch.3)",
                    f"error-correction scenario (Table 3.1 cases, Fig. 3.4 tasks; the thesis: {teleoperated} "
                    "keyboard-teleoperated demonstrations per case)")


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="data_demonstrations",
    title="Robot cells and scripted-expert demonstrations (Ch.3, Ch.4)",
    note="robosuite 1.5.1 UR5e with our suction cup on MuJoCo 3.9.0, not the thesis' CoppeliaSim UR10; "
         "demonstrations come from a scripted expert, not keyboard teleoperation. Rendered demonstrations: "
         "[videos/](videos/).",
    studies=(Study("data/collect_ch4"), Study("data/collect_ch3")),
    extra=tuple(("experiment=data/render_demo", *overrides) for overrides in VIDEOS.values()),
)
