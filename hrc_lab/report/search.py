"""A hyper-parameter study (``hydra/sweeper=optuna``, :mod:`hrc_lab.search`) read back from MLflow: one row per trial
(its run, status, the value of the study's objective and the values of the search-space keys), for a report section
or a look at a study, and the end-of-study summary printed and logged by :class:`hrc_lab.search.StudyCallback`."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from omegaconf import DictConfig, OmegaConf


def study_trials(tracking_uri: str, experiment: str, study: str) -> pd.DataFrame:
    """The trials of ``study`` in ``experiment`` (its job runs, tag ``study``; not the summary run), oldest first:
    ``run_id``, ``run_name``, ``status``, ``value`` (the objective metric, NaN for a failed trial) and one column per
    search-space key (the run's logged config value)."""
    from mlflow.tracking import MlflowClient

    from hrc_lab.tracking import resolve_tracking_uri

    client = MlflowClient(resolve_tracking_uri(tracking_uri))
    found = client.get_experiment_by_name(experiment)
    if found is None:
        return pd.DataFrame()
    runs = client.search_runs([found.experiment_id], f"tags.study = '{study}'",
                              order_by=["attributes.start_time ASC"], max_results=10000)
    rows = []
    for run in runs:
        tags = run.data.tags
        if tags.get("kind") == "summary":  # (a != filter would drop the runs without a kind tag)
            continue
        keys = [k for k in tags.get("search_keys", "").split(",") if k]
        chosen = dict(item.split("=", 1) for item in tags.get("overrides", "").split() if "=" in item)
        rows.append({"run_id": run.info.run_id, "run_name": run.info.run_name, "status": run.info.status,
                     "value": run.data.metrics.get(tags.get("objective", ""), float("nan")),
                     **{key: chosen.get(key, _param(run.data.params, key)) for key in keys}})
    return pd.DataFrame(rows)


def _param(params: dict[str, str], key: str) -> str | None:
    """A search key's value in a run's logged config (when its override is not in the ``overrides`` tag); a config
    group (e.g. ``grasp``) by its ``name``."""
    key = key.lstrip("+~")
    return params.get(key, params.get(f"{key}.name"))


def best_trial(trials: pd.DataFrame, direction: str) -> pd.Series | None:
    """The finished trial with the best value (``direction``: maximize or minimize), or None."""
    done = trials[(trials["status"] == "FINISHED") & trials["value"].notna()] if not trials.empty else trials
    if done.empty:
        return None
    return done.loc[done["value"].idxmax() if direction == "maximize" else done["value"].idxmin()]


def report_study(config: DictConfig, study: str, objective: str) -> None:
    """At the end of an Optuna sweep of ``config``: print the trials of ``study`` and its best trial by
    ``objective`` (the names :mod:`hrc_lab.search` gives them), and log both (with the sweeper's
    ``optimization_results.yaml``) as a summary run tagged ``kind=summary`` and ``study``."""
    from hrc_lab.tracking import LoggerConfig, RunTracker

    sweep_dir = Path(config.hydra.sweep.dir)
    uri = config.logger.tracking_uri
    direction = str(OmegaConf.select(config, "hydra.sweeper.direction", default="minimize")).split(".")[-1]
    trials = study_trials(uri, config.name, study)
    best = best_trial(trials, direction)
    shown = trials.drop(columns=["run_id"]).to_markdown(index=False) if not trials.empty else "(no trial runs)"
    if best is None:
        line = f"hrc-lab: study {study}: no finished trial"
    else:
        keys = [c for c in trials.columns if c not in ("run_id", "run_name", "status", "value")]
        params = ", ".join(f"{k}={best[k]}" for k in keys)
        line = (f"hrc-lab: study {study}: best trial {best['run_name']} (MLflow run {best['run_id']}): "
                f"{objective}={best['value']:.4g} ({direction}) with {params}")
    logger = LoggerConfig(tracking_uri=uri, artifact_root=config.logger.artifact_root)
    tags = {"kind": "summary", "study": study, "sweep": sweep_dir.name, "table": str(config.table),
            "chapter": str(config.chapter), "variant": "search", "objective": str(objective)}
    if best is not None:
        tags["best_run"] = str(best["run_id"])
    with RunTracker(logger, config.name, f"{config.name}-study-{study}", tags) as tracker:
        if best is not None:
            tracker.log_metrics({f"best_{objective}": float(best["value"]), "n_trials": float(len(trials))})
        tracker.log_text(f"{shown}\n\n{line}\n", "study/trials.md")
        tracker.log_artifact(sweep_dir / "optimization_results.yaml", "study")
    print(f"\nStudy {study} ({len(trials)} trials, {objective}, {direction}):\n{shown}\n{line}")
