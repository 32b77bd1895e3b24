"""Figures a Ch.5 perception run logs: the confusion matrix of Fig. 5.5 and a strip of annotated session frames."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from hrc_lab.perception.sessions import segments_of


def confusion_figure(confusion: np.ndarray, names: list[str], title: str) -> Figure:
    """Fig. 5.5: row-normalised confusion matrix with counts."""
    fig = Figure(figsize=(8.5, 7.5))
    ax = fig.subplots()
    rates = confusion / np.maximum(confusion.sum(1, keepdims=True), 1)
    ax.imshow(rates, cmap="Blues", vmin=0, vmax=1)
    ax.set_xticks(range(len(names)), names, rotation=90, fontsize=8)
    ax.set_yticks(range(len(names)), names, fontsize=8)
    for i, j in zip(*np.nonzero(confusion)):
        ax.text(j, i, str(confusion[i, j]), ha="center", va="center", fontsize=6,
                color="white" if rates[i, j] > 0.5 else "black")
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title)
    fig.tight_layout()
    return fig


def session_strip(annotated: list[np.ndarray], labels: list[str]) -> Figure:
    """Annotated frames of a session (``labels``: its true frame labels) just after the end of its first six
    segments with a hand action, each titled with that action."""
    runs = [r for r in segments_of(labels) if r[0] != "none"][:6]
    fig = Figure(figsize=(12, 6))
    axes = fig.subplots(2, 3)
    for ax, (label, _, end) in zip(axes.ravel(), runs):
        ax.imshow(annotated[min(end + 2, len(annotated) - 1)])
        ax.set_title(f"true: {label}", fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    return fig
