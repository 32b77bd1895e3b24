"""Report section of the Ch.4 motion module: Table 4.2 (sub-goal regressors, R^2 and closed-loop success)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from hrc_lab.report.ch4_conditions import conditions_paragraph
from hrc_lab.report.plan import Plan, Study
from hrc_lab.report.plots import success_bars
from hrc_lab.report.runs import NOT_LOGGED, amount, keyed, mean_std, over_seeds, setting
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, thesis_cells, thesis_fmt, thesis_results, thesis_value

CELLS = ["2of3", "3of3", "3of5", "4of5"]
METHODS = ["tc_vi", "vi", "gpr", "mlp"]
LABELS = {"tc_vi": "Ours (task-conditioned VI)", "vi": "VI", "gpr": "GPR", "mlp": "MLP"}
THESIS_KEYS = {"tc_vi": "ours", "vi": "vi", "gpr": "gpr", "mlp": "mlp"}


def _stat(stats: pd.DataFrame, method: str, cell: str) -> tuple[float, float]:
    hit = stats[(stats.method == method) & (stats.cell == cell)]
    return (hit.iloc[0]["mean"], hit.iloc[0]["std"]) if len(hit) else (np.nan, np.nan)


FITS = 0.95  # an MLP whose cross-validated R² is at least this fits its demonstrations (the thesis' best: 0.87)


def _baselines_paragraph(runs: pd.DataFrame, thesis: dict) -> list[str]:
    """What the GPR and MLP rows depend on (issue 24): the GPR's kernel and the MLP's fit, with the thesis' R²."""
    text = []
    gpr, mlp = runs[runs.method == "gpr"], runs[runs.method == "mlp"]
    if len(gpr):
        kernel = setting(gpr, "motion.gpr_kernel")
        reading = {"isotropic": "one length scale for all its standardised inputs (scikit-learn's `RBF()`)",
                   "ard": "one length scale per input (ARD)"}.get(kernel, "one length scale per input (ARD; the "
                                                                         "runs predate `motion.gpr_kernel`)")
        text += ["", f"**GPR** reads the thesis' \"RBF kernel\" as {reading}, `motion.gpr_kernel`. Its R² stays high "
                 "because held-out demonstrations resemble the training ones. In closed loop it must place products "
                 "in slots they never went to in training (each product goes to one slot there), so r at a placing "
                 "stage's start is unlike any training r with that slot's label: one length scale cannot discount "
                 "r, and the sub-goals fall back towards the mean. With one length scale per input the fit learns "
                 "that the placing sub-goals barely depend on r and carries them over (`motion.gpr_kernel=ard`, an "
                 "ablation with its own section below when its runs are in the store)."]
        sr, r2 = (gpr.groupby("cell")[key].mean() for key in ("sr", "r2"))
        text[-1] += (f" Per cell here: SR {sr.min():.2f}–{sr.max():.2f}, R² {r2.min():.2f}–{r2.max():.2f}; the thesis' "
                     f"row: SR {min(v[0] for v in thesis['gpr']['sr'])}–{max(v[0] for v in thesis['gpr']['sr'])}, "
                     f"R² {min(thesis['gpr']['r2'])}–{max(thesis['gpr']['r2'])}. The isotropic reading is the default "
                     "because it brings the row to the thesis' level, where ARD's placing sub-goals succeed far "
                     "more often than the thesis' GPR.")
    if len(mlp):
        r2, fit = thesis["mlp"]["r2"], mlp.groupby("cell").r2.mean()
        text += ["", f"**MLP** trains {setting(mlp, 'motion.steps')} steps (`motion.steps`): R² "
                 f"{fit.min():.2f}–{fit.max():.2f} here, the thesis' MLP {min(r2)}–{max(r2)} in its own "
                 "cross-validation. With fewer steps (`motion.steps=100,300`, ablation sections below when their runs "
                 "are in the store) the SR follows the fit: an MLP stopped at the thesis' R² fails as the thesis' "
                 "does. "
                 + ("This row differs from the thesis' because it is trained to convergence." if fit.min() >= FITS
                    else "This row does not fit its demonstrations either.")]
    return text


@register_section("table_4_2")
def table_4_2(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch4"]["table_4_2"]
    sr, r2 = mean_std(runs, ["method", "cell"], "sr"), mean_std(runs, ["method", "cell"], "r2")
    cells = thesis_cells(runs.cell, CELLS)
    methods = [m for m in METHODS if m in set(runs.method)]
    rows, csv = [], []
    for method in methods:
        ref = thesis[THESIS_KEYS[method]]
        row = {"method": LABELS[method]}
        for cell in cells:
            ref_r2 = thesis_value(ref["r2"], thesis["columns"], cell)  # None: a cell the thesis did not run
            ref_sr = thesis_value(ref["sr"], thesis["columns"], cell) or (None, None)
            r2_mean, r2_std = _stat(r2, method, cell)
            sr_mean, sr_std = _stat(sr, method, cell)
            row[f"{cell} R²"] = f"{fmt(r2_mean, r2_std)} ({thesis_fmt(ref_r2)})"
            row[f"{cell} SR"] = f"{fmt(sr_mean, sr_std)} ({thesis_fmt(*ref_sr)})"
            csv.append({"method": method, "cell": cell, "r2_mean": r2_mean, "r2_std": r2_std, "sr_mean": sr_mean,
                        "sr_std": sr_std, "thesis_r2": ref_r2, "thesis_sr": ref_sr[0]})
        rows.append(row)
    failures = runs.groupby(["method"])[[c for c in runs.columns if c.startswith("fail_")]].mean()
    failures = failures.reindex(methods).rename(index=LABELS).round(2)
    ours = runs[runs.method == "tc_vi"]
    latency = ref_ms = None
    if len(ours):
        latency = ours.planning_ms.mean()
        ref_ms = thesis_results()["ch4"]["text"]["subgoal_planning_ms_per_subgoal"]
    folds = setting(runs, "protocol.cv_folds")
    folds = f"{folds}-fold (`protocol.cv_folds`)" if folds != NOT_LOGGED else "k-fold (`protocol.cv_folds` not logged)"
    text = [
        f"R² of the sub-goal regressor by {folds} cross-validation over demonstrations, and success rate (SR) of "
        f"{amount(runs, 'protocol.trials', 'closed-loop trials')} (CASE 1 and CASE 2 alternating, every goal "
        "configuration; trained on one packing arrangement per selection, "
        f"{amount(runs, 'protocol.demos', 'scripted-expert demonstrations')} per cell and seed) of the two-level "
        "motion module with ground-truth reasoning outputs, δr = "
        f"{keyed(runs, 'env.sim.success_threshold', 'm')}; "
        f"{over_seeds(runs)}. Thesis values in brackets.",
        "",
        pd.DataFrame(rows).to_markdown(index=False),
        "",
        "Why trials failed (share of trials): `pick` the cup never gripped the product, `placement` a product "
        "ended more than δr from its slot, `collision` a forbidden contact (Eq. 4.7), `horizon` out of steps.",
        "",
        failures.reset_index().to_markdown(index=False),
    ]
    if latency is not None:
        steps = ours.steps_per_object.mean()
        text += ["", f"Planning latency of our sub-goal planner: **{latency:.2f} ms** per sub-goal on one CPU core "
                     f"(thesis {ref_ms} ms); {steps:.1f} control steps per product (thesis 27-47)."]
    text += _baselines_paragraph(runs, thesis)
    text += conditions_paragraph(runs, "the motion module reads the requested product's and the box's positions "
                                       "(Sec. 4.2.2), so both ranges are its test conditions.")
    return Section("Table 4.2: sub-goal regressors and the motion module", "\n".join(text), pd.DataFrame(csv),
                   {"table_4_2.png": success_bars(pd.DataFrame(csv), cells, methods, LABELS, "Table 4.2")})


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch4_motion",
    title="Ch.4 motion module: task-conditioned sub-goal planner and NDP vs. VI, GPR, MLP",
    note="Closed-loop trials run in our robosuite UR5e cell, not the thesis' CoppeliaSim UR10; demonstrations "
         "come from the scripted expert.",
    studies=(Study("ch4/table_4_2"),),
)
