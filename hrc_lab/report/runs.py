"""Fetching the MLflow runs of an experiment as one DataFrame row per run.

Runs are selected by *variant*: a job whose only overrides are the experiment file's own sweep keys (and launcher
or Hydra settings) is variant ``default``; any other override (e.g. ``protocol.demos=60``) makes an ablation
variant, tagged ``variant`` = ``v`` + 8 hex digits and ``variant_overrides`` = the extra overrides. Reports read
each variant apart, so an ablation never replaces a default run. Runs logged before the tag existed are
``default``. A run whose logged config today's defaults no longer give joins the variant of its overrides plus the
changed settings, and an override that today's defaults already give leaves its variant
(:mod:`hrc_lab.report.defaults`). Only FINISHED runs are ever read (never RUNNING, KILLED or FAILED ones).
"""

from __future__ import annotations

import pandas as pd
from mlflow.tracking import MlflowClient

from hrc_lab.report.defaults import PARAM_PREFIX, pin_changed_defaults
from hrc_lab.tracking import resolve_tracking_uri

KEY_TAGS = ("scenario", "cell", "method", "seed")  # scenario: the cell plus the robot-cell case
DEFAULT_VARIANT = "default"
NOT_LOGGED = "not logged"


def _finished_runs(tracking_uri: str, experiment: str, sweep: str | None) -> pd.DataFrame:
    """Every FINISHED job run of ``experiment`` (optionally one sweep's), newest first; no summary runs."""
    client = MlflowClient(resolve_tracking_uri(tracking_uri))
    found = client.get_experiment_by_name(experiment)
    if found is None:
        return pd.DataFrame()
    query = "attributes.status = 'FINISHED'"
    if sweep:
        query += f" and tags.sweep = '{sweep}'"
    runs = client.search_runs([found.experiment_id], query, order_by=["attributes.start_time DESC"], max_results=50000)
    rows = [
        {
            "run_id": r.info.run_id,
            "start_time": r.info.start_time,
            "end_time": r.info.end_time,
            "status": r.info.status,
            **{f"{PARAM_PREFIX}{k}": v for k, v in r.data.params.items()},
            **r.data.tags,
            **r.data.metrics,
        }
        for r in runs
        if r.data.tags.get("kind") != "summary"
    ]
    if not rows:
        return pd.DataFrame()
    frame = pd.DataFrame(rows).sort_values("start_time", ascending=False, kind="stable")
    frame["seed"] = frame["seed"].astype(int)
    if "scenario" not in frame:  # runs logged before the scenario tag existed
        frame["scenario"] = frame["cell"]
    frame["scenario"] = frame["scenario"].fillna(frame["cell"])
    for column, missing in (("sweep", "none"), ("variant", DEFAULT_VARIANT), ("variant_overrides", "")):
        frame[column] = frame[column].fillna(missing) if column in frame else missing  # older runs lack the tag
    return frame.reset_index(drop=True)


def fetch_runs(
    tracking_uri: str, experiment: str, sweep: str | None = None, variant: str | None = DEFAULT_VARIANT
) -> pd.DataFrame:
    """Finished runs of ``experiment`` of one ``variant`` (``None``: every variant), optionally of one sweep, the
    newest per (scenario, cell, method, seed) within its variant. Columns: ``run_id``, ``start_time``, the tags
    (``sweep`` and ``variant`` always), one column per final metric and ``param.<key>`` per logged param."""
    return newest_runs(finished_runs(tracking_uri, experiment, sweep), variant)


def finished_runs(tracking_uri: str, experiment: str, sweep: str | None = None) -> pd.DataFrame:
    """Every finished job run of ``experiment`` (optionally of one sweep), newest first, in the variant today's
    defaults give it (:func:`hrc_lab.report.defaults.pin_changed_defaults`)."""
    return pin_changed_defaults(_finished_runs(tracking_uri, experiment, sweep))


def newest_runs(frame: pd.DataFrame, variant: str | None = DEFAULT_VARIANT) -> pd.DataFrame:
    """Of :func:`finished_runs`' ``frame``: the runs of ``variant`` (None: every variant), the newest per (scenario,
    cell, method, seed) within its variant."""
    if frame.empty:
        return frame
    if variant is not None:
        frame = frame[frame["variant"] == variant]
    frame = frame.drop_duplicates(subset=[*KEY_TAGS, "variant"], keep="first")
    return frame.reset_index(drop=True)


def default_runs_of(runs: pd.DataFrame) -> pd.DataFrame:
    """The default runs of the cells of an ablation's ``runs``, of the same experiment (tag ``experiment``) in the
    store they logged to (param ``logger.tracking_uri``): what an ablation section compares its settings with.
    Empty for default runs, or when the experiment or the store is not logged."""
    uri = f"{PARAM_PREFIX}logger.tracking_uri"
    if runs.empty or not {uri, "experiment", "variant"} <= set(runs) or set(runs["variant"]) == {DEFAULT_VARIANT}:
        return pd.DataFrame()
    default = fetch_runs(runs[uri].iloc[0], runs["experiment"].iloc[0])
    return default[default["cell"].isin(runs["cell"])] if not default.empty else default


def variants_of(runs: pd.DataFrame) -> dict[str, str]:
    """Variant -> its overrides ("" for default) among ``runs``: default first, then ablations by overrides."""
    if runs.empty:
        return {}
    pairs = runs.drop_duplicates("variant")[["variant", "variant_overrides"]]
    found = dict(zip(pairs["variant"], pairs["variant_overrides"].astype(str)))
    ordered = sorted(found.items(), key=lambda item: (item[0] != DEFAULT_VARIANT, item[1], item[0]))
    return dict(ordered)


def sweeps_line(runs: pd.DataFrame) -> str:
    """ "Runs: sweep 2026-11-23_19-31-20 (24 runs)", several sweeps comma-separated with their run counts."""
    counts = runs["sweep"].value_counts().sort_index()
    plural = "sweeps" if len(counts) > 1 else "sweep"
    listed = ", ".join(f"{sweep} ({n} run{'s' if n != 1 else ''})" for sweep, n in counts.items())
    variants = sorted(set(runs["variant"]) - {DEFAULT_VARIANT}) if "variant" in runs else []
    suffix = f"; variant {', '.join(variants)}" if variants else ""
    return f"Runs: {plural} {listed}{suffix}"


def setting_values(runs: pd.DataFrame, key: str) -> list[str]:
    """The distinct logged values of the config key ``key`` (e.g. ``protocol.n_folds``) among ``runs``."""
    column = f"{PARAM_PREFIX}{key}"
    if column not in runs:
        return []
    return sorted({str(v) for v in runs[column].dropna()}, key=number_first)


def setting(runs: pd.DataFrame, key: str) -> str:
    """The logged value of a config key as text ("5"; "20 or 60" if the runs differ), "not logged" if no run
    logged it (runs older than the key)."""
    values = setting_values(runs, key)
    return " or ".join(values) if values else NOT_LOGGED


def amount(runs: pd.DataFrame, key: str, noun: str) -> str:
    """ "180 test scenarios" from the logged ``key``, or "test scenarios (`protocol.missing_tests` not logged)"."""
    value = setting(runs, key)
    return f"{noun} (`{key}` {NOT_LOGGED})" if value == NOT_LOGGED else f"{value} {noun}"


def keyed(runs: pd.DataFrame, key: str, unit: str = "") -> str:
    """ "0.06 m (`env.sim.success_threshold`)" from the logged ``key``, or "`env.sim.success_threshold` (not
    logged)"."""
    value = setting(runs, key)
    return f"`{key}` ({NOT_LOGGED})" if value == NOT_LOGGED else f"{value}{' ' + unit if unit else ''} (`{key}`)"


def setting_number(runs: pd.DataFrame, key: str) -> float | None:
    """The logged value of a numeric config key when every run that logged it agrees, else None."""
    values = setting_values(runs, key)
    if len(values) != 1:
        return None
    try:
        return float(values[0])
    except ValueError:
        return None


def number_first(value: str):
    """Sort key: numbers by value first, then other text."""
    try:
        return (0, float(value), value)
    except ValueError:
        return (1, 0.0, value)


def over_seeds(runs: pd.DataFrame, listed: bool = True, start: bool = False) -> str:
    """What a section's "±" means, in words: "mean ± std over seeds [0, 1, 2]" ("mean ± std over seeds" unless
    ``listed``), or "one seed (0): no spread" for runs of one seed, whose cells print no spread
    (:func:`hrc_lab.report.thesis.seeds_of`). ``start``: capitalised, to begin a sentence."""
    seeds = sorted(runs.seed.unique())
    if len(seeds) == 1:
        text = f"one seed ({seeds[0]}): no spread"
    else:
        text = f"mean ± std over seeds {seeds}" if listed else "mean ± std over seeds"
    return text[0].upper() + text[1:] if start else text


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


def run_clients(runs: pd.DataFrame):
    """(run_id, MlflowClient of the store the run logged to) for every run; none when the runs' tracking URI is not
    logged."""
    if runs.empty or f"{PARAM_PREFIX}logger.tracking_uri" not in runs:
        return
    for run_id, uri in zip(runs.run_id, runs[f"{PARAM_PREFIX}logger.tracking_uri"]):
        yield run_id, MlflowClient(resolve_tracking_uri(uri))


def histories(runs: pd.DataFrame, metric: str) -> pd.DataFrame:
    """Every run's history of ``metric``: columns run_id, step, value (empty when none was logged)."""
    rows = []
    for run_id, client in run_clients(runs):
        history = client.get_metric_history(run_id, metric)
        rows += [{"run_id": run_id, "step": m.step, "value": m.value} for m in history]
    return pd.DataFrame(rows, columns=["run_id", "step", "value"])


def run_tables(runs: pd.DataFrame, name: str) -> pd.DataFrame:
    """The table every run logged as ``tables/<name>.csv`` (``RunTracker.log_table``), concatenated with a
    ``run_id`` column; runs that logged none are left out (all of them when the runs' tracking URI is not
    logged)."""
    import tempfile

    frames = []
    for run_id, client in run_clients(runs):
        if not any(a.path == f"tables/{name}.csv" for a in client.list_artifacts(run_id, "tables")):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            path = client.download_artifacts(run_id, f"tables/{name}.csv", tmp)
            frames.append(pd.read_csv(path).assign(run_id=run_id))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["run_id"])
