"""``hrc-lab``: run any experiment, e.g. ``hrc-lab experiment=ch4/table_4_1``.

One Hydra job = one MLflow run named ``<experiment>-<method>-<scenario>-seed<k>`` (scenario: the env's table
column, e.g. ``4of5`` or ``3goals``, plus the robot-cell case when it is not CASE 1, e.g.
``4of5_case2``), followed by ``-v<hash>`` when the job changes anything beyond the experiment file's own sweep keys
or composes a config file that is not the repository's, e.g. ``--config-dir <dir>`` with ``<dir>/env/<name>.yaml``
(its *variant*: an ablation or a user's own config is never mistaken for the default protocol). The config is
validated before anything heavy is imported, so a bad key fails within a second. Sweeps use Hydra's launchers
(``hydra/launcher=joblib`` locally; submitit or Ray on a cluster).

Exit codes: 0 success, 1 the job failed (MLflow status FAILED), 2 config error (no run is created: a value
``validate_config`` rejects, or one Hydra cannot compose, e.g. an unknown group option, whose message lists the
options), 143 / 130 killed by SIGTERM / SIGINT (MLflow status KILLED, tag ``signal``).
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.errors import ConfigCompositionException, MissingConfigException, OverrideParseException
from omegaconf import DictConfig

from hrc_lab.config import LOGGERS, ConfigError, ValidatedConfig, validate_config
from hrc_lab.console import headline, quiet_third_party
from hrc_lab.interrupts import RunInterrupted, exit_interrupted, signals_raise
from hrc_lab.run_naming import CONF_DIR, is_optuna, job_tags, method_of, run_name

log = logging.getLogger("hrc_lab")


def check_resumable(validated: ValidatedConfig, cfg: DictConfig) -> None:
    """``resume_from`` must name a run of this experiment that was killed or failed, not tagged ``invalidated``
    (results known to be wrong, the tag says why), with the same config (a key added since it ran as its schema
    default; where runs log and write aside)."""
    from mlflow.exceptions import MlflowException
    from mlflow.tracking import MlflowClient
    from omegaconf import OmegaConf

    from hrc_lab.tracking import changed_settings, flatten, job_settings, resolve_tracking_uri, schema_defaults

    client = MlflowClient(resolve_tracking_uri(validated.logger.tracking_uri))
    try:
        parent = client.get_run(validated.resume_from)
    except MlflowException:
        raise ConfigError(
            f"resume_from: no MLflow run {validated.resume_from} in {validated.logger.tracking_uri}"
        ) from None
    if parent.data.tags.get("experiment") != cfg.name:
        raise ConfigError(f"resume_from: run {validated.resume_from} belongs to experiment "
                          f"{parent.data.tags.get('experiment')!r}, not {cfg.name!r}")
    if "invalidated" in parent.data.tags:
        raise ConfigError(f"resume_from: run {validated.resume_from} is invalidated "
                          f"({parent.data.tags['invalidated']}); start the job afresh")
    if parent.info.status in ("FINISHED", "RUNNING"):
        hint = ""
        if parent.info.status == "RUNNING":
            hint = " (if its process is gone, `hrc-lab-runs stale` marks it KILLED)"
        raise ConfigError(f"resume_from: run {validated.resume_from} is {parent.info.status}; only a KILLED or "
                          f"FAILED run can be resumed{hint}")
    ours = flatten(OmegaConf.to_container(cfg, resolve=True))
    job = job_settings(cfg)  # where the runs log and write may differ (another working directory, a moved store)
    theirs = parent.data.params
    defaults = schema_defaults(cfg)  # what the run had for a key it did not log (added since)
    differ = [key for key in changed_settings(theirs, ours, defaults) if key in job or key not in ours]
    if differ:
        shown = ", ".join(f"{k}={theirs.get(k, defaults.get(k))!r} there, {ours.get(k)!r} here" for k in differ[:5])
        raise ConfigError(f"resume_from: run {validated.resume_from} had another config: {shown}")


def run(cfg: DictConfig) -> dict[str, float]:
    """Validate, then run the experiment's protocol inside one MLflow run; return its metrics. SIGTERM/SIGINT
    raise :class:`RunInterrupted` inside the job, which marks the run KILLED."""
    with signals_raise():
        return _run(cfg)


def _run(cfg: DictConfig) -> dict[str, float]:
    validated = validate_config(cfg)
    if validated.resume_from:
        check_resumable(validated, cfg)

    import lightning.pytorch as pl
    import torch

    from hrc_lab.experiments import PROTOCOLS
    from hrc_lab.run_context import RunContext
    from hrc_lab.search import trial_tags

    torch.set_num_threads(cfg.num_threads)
    pl.seed_everything(cfg.seed, workers=True, verbose=False)
    protocol = PROTOCOLS.load(validated.protocol.name)
    scenario = getattr(validated.env, "scenario", validated.env.cell)
    tags = {
        "chapter": str(cfg.chapter),
        "table": str(cfg.table),
        "experiment": str(cfg.name),
        "method": method_of(cfg),
        "cell": validated.env.cell,
        "scenario": scenario,
        "seed": str(cfg.seed),
        **job_tags(),
        **trial_tags(cfg, HydraConfig.get()),  # study, objective, search_keys under hydra/sweeper=optuna
    }
    output_dir = Path(HydraConfig.get().runtime.output_dir)
    name = run_name(cfg, scenario, tags["variant"])
    tracker = LOGGERS.build(validated.logger, experiment=cfg.name, run_name=name, tags=tags,
                            parent_run_id=validated.resume_from)
    with tracker:
        tracker.log_config(cfg)
        tracker.log_artifact(output_dir / ".hydra", "hydra")
        tracker.log_text(str(output_dir.resolve()), "hydra/output_dir.txt")
        metrics = protocol(RunContext(validated, tracker, cfg.seed, output_dir))
        tracker.log_metrics(metrics)
    log.info("%s: %s (MLflow run %s)", name, headline(metrics), tracker.run_id)
    return metrics


@hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name="config")
def _hydra_main(cfg: DictConfig) -> float | None:
    quiet_third_party()  # in a launcher's worker too (a joblib worker runs this function, not main())
    try:
        metrics = run(cfg)
    except ConfigError as err:
        print(f"hrc-lab: config error: {err}", file=sys.stderr)
        sys.exit(2)
    except RunInterrupted as err:
        print(f"hrc-lab: {interrupted_message(err)}", file=sys.stderr)
        exit_interrupted(err)
    except Exception as err:
        from hrc_lab.tracking import TrackingUnavailable  # imported by run() already (kept off the config path)

        if not isinstance(err, TrackingUnavailable):
            raise
        print(f"hrc-lab: {err}", file=sys.stderr)
        sys.exit(1)
    return objective_value(cfg, metrics)


def interrupted_message(err: RunInterrupted) -> str:
    """What an interrupted job tells its user: the MLflow run it marked KILLED and how to resume it, or that it
    was stopped before it started one."""
    if err.killed_run_id is None:
        return f"{err} before its MLflow run started; nothing to resume"
    return f"{err}; MLflow run {err.killed_run_id} is marked KILLED (resume with resume_from={err.killed_run_id})"


def objective_value(cfg: DictConfig, metrics: dict[str, float]) -> float | None:
    """The value an Optuna sweeper optimises: the metric ``search.objective`` names (conf/search; docs/search.md),
    else ``sr``. Under the Optuna sweeper a missing metric is a config error naming the metrics there are."""
    from hrc_lab.search import objective_of

    objective = objective_of(cfg)
    if objective not in metrics and is_optuna(HydraConfig.get()):
        print(f"hrc-lab: config error: search.objective: {objective!r} is not a metric of experiment {cfg.name}; "
              f"it returns {sorted(metrics)}", file=sys.stderr)
        sys.exit(2)
    return metrics.get(objective)


COMPOSITION_ERRORS = (ConfigCompositionException, MissingConfigException, OverrideParseException)


def main() -> None:
    quiet_third_party()
    if not CONF_DIR.is_dir():
        sys.exit(f"hrc-lab: no config folder at {CONF_DIR}; install hrc_lab from a checkout with `pip install -e .`")
    # Hydra reports a config it cannot compose like a failed job (exit 1); with its errors raised, hrc-lab tells them
    # apart (a failed job's traceback is then printed in full)
    os.environ.setdefault("HYDRA_FULL_ERROR", "1")
    try:
        _hydra_main()
    except COMPOSITION_ERRORS as err:
        cause = f"\n{err.__cause__}" if err.__cause__ is not None else ""
        print(f"hrc-lab: config error: {err}{cause}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
