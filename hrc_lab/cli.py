"""``hrc-lab``: run any experiment, e.g. ``hrc-lab experiment=ch4/table_4_1``.

One Hydra job = one MLflow run named ``<experiment>-<method>-<scenario>-seed<k>`` (scenario: the env's table
column, e.g. ``4of5`` or ``3goals``, plus the robot-cell case when it is not CASE 1, e.g.
``4of5_case2``). The config is validated before
anything heavy is imported, so a bad key fails within a second. Sweeps use Hydra's launchers
(``hydra/launcher=joblib`` locally; submitit or Ray on a cluster).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from hrc_lab.config import ConfigError, validate_config

CONF_DIR = Path(__file__).resolve().parents[1] / "conf"
log = logging.getLogger("hrc_lab")


def method_of(cfg: DictConfig) -> str:
    """The method a run compares: the first of its perception, reasoning, motion and grasp modules that is not
    "none" (a Ch.5 run with a trained action detector is named after the detector, not the planner it feeds)."""
    for group in ("perception", "reasoning", "motion", "grasp"):
        name = (cfg.get(group) or {}).get("name", "none")
        if name != "none":
            return name
    return "none"


def run_name(cfg: DictConfig, scenario: str) -> str:
    return f"{cfg.name}-{method_of(cfg)}-{scenario}-seed{cfg.seed}"


def sweep_id() -> str:
    """The sweep a job belongs to (its sweep folder relative to runs/), or "none" for a single run."""
    hydra_cfg = HydraConfig.get()
    if hydra_cfg.mode != RunMode.MULTIRUN:
        return "none"
    return Path(hydra_cfg.sweep.dir).name


def run(cfg: DictConfig) -> dict[str, float]:
    """Validate, then run the experiment's protocol inside one MLflow run; return its metrics."""
    validated = validate_config(cfg)

    import lightning.pytorch as pl
    import torch

    from hrc_lab.experiments import PROTOCOLS
    from hrc_lab.experiments.context import RunContext
    from hrc_lab.tracking import RunTracker

    torch.set_num_threads(cfg.num_threads)
    pl.seed_everything(cfg.seed, workers=True, verbose=False)
    protocol = PROTOCOLS.load(cfg.protocol.name)
    scenario = getattr(validated.env, "scenario", validated.env.cell)
    tags = {
        "chapter": str(cfg.chapter),
        "table": str(cfg.table),
        "experiment": str(cfg.name),
        "method": method_of(cfg),
        "cell": validated.env.cell,
        "scenario": scenario,
        "seed": str(cfg.seed),
        "sweep": sweep_id(),
    }
    output_dir = Path(HydraConfig.get().runtime.output_dir)
    name = run_name(cfg, scenario)
    with RunTracker(validated.logger, cfg.name, name, tags) as tracker:
        tracker.log_config(cfg)
        metrics = protocol(RunContext(validated, tracker, cfg.seed))
        tracker.log_metrics(metrics)
        tracker.log_artifact(output_dir / ".hydra", "hydra")
        tracker.log_text(str(output_dir.resolve()), "hydra/output_dir.txt")
    shown = ", ".join(f"{k}={v:.3f}" for k, v in metrics.items() if "latency" not in k and not k.startswith("n_"))
    log.info("%s: %s (MLflow run %s)", name, shown, tracker.run_id)
    return metrics


@hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name="config")
def _hydra_main(cfg: DictConfig) -> float | None:
    try:
        metrics = run(cfg)
    except ConfigError as err:
        print(f"hrc-lab: config error: {err}", file=sys.stderr)
        sys.exit(2)
    return metrics.get("sr")  # the value an Optuna sweeper would optimise


def main() -> None:
    if not CONF_DIR.is_dir():
        sys.exit(f"hrc-lab: no config folder at {CONF_DIR}; install hrc_lab from a checkout with `pip install -e .`")
    _hydra_main()


if __name__ == "__main__":
    main()
