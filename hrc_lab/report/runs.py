"""Fetching the MLflow runs of an experiment as one DataFrame row per run."""

from __future__ import annotations

import pandas as pd
from mlflow.tracking import MlflowClient

from hrc_lab.tracking import resolve_tracking_uri

KEY_TAGS = ("scenario", "cell", "method", "seed")  # scenario: the cell plus the robot-cell case


def fetch_runs(tracking_uri: str, experiment: str, sweep: str | None = None) -> pd.DataFrame:
    """Finished runs of ``experiment`` (optionally one sweep's), the newest per (cell, method, seed), with tag
    columns and one column per final metric."""
    client = MlflowClient(resolve_tracking_uri(tracking_uri))
    found = client.get_experiment_by_name(experiment)
    if found is None:
        return pd.DataFrame()
    query = "attributes.status = 'FINISHED'"
    if sweep:
        query += f" and tags.sweep = '{sweep}'"
    runs = client.search_runs([found.experiment_id], query, order_by=["attributes.start_time DESC"], max_results=50000)
    rows = [
        {"run_id": r.info.run_id, "start_time": r.info.start_time, **r.data.tags, **r.data.metrics}
        for r in runs
        if r.data.tags.get("kind") != "summary"
    ]
    if not rows:
        return pd.DataFrame()
    frame = pd.DataFrame(rows)
    frame["seed"] = frame["seed"].astype(int)
    if "scenario" not in frame:  # runs logged before the scenario tag existed
        frame["scenario"] = frame["cell"]
    frame["scenario"] = frame["scenario"].fillna(frame["cell"])
    return frame.drop_duplicates(subset=list(KEY_TAGS), keep="first").reset_index(drop=True)


def mean_std(frame: pd.DataFrame, by: list[str], metric: str) -> pd.DataFrame:
    """Mean, standard deviation (ddof=0, as a spread over seeds) and number of seeds of a metric per group."""
    if metric not in frame:
        return pd.DataFrame(columns=[*by, "mean", "std", "n"])
    grouped = frame.dropna(subset=[metric]).groupby(by)[metric]
    return grouped.agg(mean="mean", std=lambda s: s.std(ddof=0), n="count").reset_index()


def spread(frame: pd.DataFrame, metric: str) -> tuple[float, float]:
    """Mean and standard deviation (ddof=0) of a metric over the rows of ``frame``; NaN when it has no value."""
    values = frame[metric].dropna() if metric in frame else pd.Series(dtype=float)
    return (float(values.mean()), float(values.std(ddof=0))) if len(values) else (float("nan"), float("nan"))
