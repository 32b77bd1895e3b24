"""Plots shared by report sections."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from hrc_lab.report.thesis import one_seed  # noqa: E402


def success_bars(frame: pd.DataFrame, cells: list[str], groups: list[str], labels: dict[str, str], title: str,
                 group_col: str = "method", thesis_col: str = "thesis_sr"):
    """Success rate per cell: one bar per group (``sr_mean`` ± ``sr_std`` over seeds; in a section of one seed, no
    error bar), the thesis' value as a black tick on each bar. ``frame`` has a row per (group, cell)."""
    fig, ax = plt.subplots(figsize=(8, 3.6))
    width = 0.8 / max(len(groups), 1)
    for i, group in enumerate(groups):
        part = frame[frame[group_col] == group].set_index("cell").reindex(cells)
        x = np.arange(len(cells)) + (i - (len(groups) - 1) / 2) * width
        ax.bar(x, part.sr_mean, width, yerr=None if one_seed() else part.sr_std, capsize=2,
               label=labels.get(group, group))
        ax.scatter(x, part[thesis_col].astype(float), marker="_", s=150, color="black", linewidths=2, zorder=3)
    ax.set_xticks(range(len(cells)), cells)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("success rate")
    ours = "ours (one seed)" if one_seed() else "ours (mean ± std over seeds)"
    ax.set_title(f"{title} - bars: {ours}; black ticks: thesis", fontsize=10)
    ax.legend(ncol=len(groups), fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.1), frameon=False)
    fig.tight_layout()
    return fig
