"""Validation of a composed config before any work starts (light: imports no torch, lightning or mlflow).

Hydra already refuses command-line overrides of keys that do not exist (struct mode); this module checks what
the YAML files and ``+key=`` additions may still get wrong: unknown keys, wrong types and impossible values in
every group, naming the full key in the error (``env.n_selected``, ``reasoning.hiden``, ``trainer.max_epoch``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from hrc_lab.registry import ConfigError, Registry

TOP_LEVEL_KEYS = {
    "name",
    "chapter",
    "table",
    "seed",
    "num_threads",
    "protocol",
    "env",
    "reasoning",
    "motion",
    "perception",
    "grasp",
    "trainer",
    "logger",
    "paths",
}


@dataclass
class LoggerConfig:
    tracking_uri: str = "sqlite:///runs/mlflow.db"
    artifact_root: str = "runs/mlartifacts"  # where new MLflow experiments keep artifacts (local stores)

    def __post_init__(self) -> None:
        if "://" not in self.tracking_uri and not self.tracking_uri.startswith("databricks"):
            raise ValueError(
                "logger.tracking_uri must be a URI such as sqlite:///runs/mlflow.db or http://127.0.0.1:5000, "
                f"got {self.tracking_uri!r}"
            )


LOGGERS = Registry("logger")
LOGGERS.register("mlflow", LoggerConfig, "hrc_lab.tracking:RunTracker")


@dataclass
class TrainerConfig:
    """The Lightning ``Trainer`` arguments a run may set (``conf/trainer``); add one here to expose it."""

    _target_: str = "lightning.pytorch.Trainer"
    accelerator: str = "cpu"
    devices: Any = 1
    strategy: str = "auto"
    num_nodes: int = 1
    precision: Any = "32-true"
    max_epochs: int = 30
    max_steps: int = -1
    deterministic: bool = True
    log_every_n_steps: int = 50
    enable_progress_bar: bool = True
    enable_model_summary: bool = False
    enable_checkpointing: bool = False
    gradient_clip_val: float | None = None
    default_root_dir: str | None = None

    def __post_init__(self) -> None:
        if self.max_epochs < 1 and self.max_steps < 1:
            raise ValueError("trainer.max_epochs or trainer.max_steps must be >= 1")


@dataclass
class ValidatedConfig:
    """The typed view of a run's config that protocols receive (``raw`` keeps the composed DictConfig)."""

    raw: DictConfig
    env: Any
    reasoning: Any
    motion: Any
    perception: Any
    grasp: Any
    protocol: Any
    logger: LoggerConfig


def _validate_trainer(node: DictConfig) -> None:
    try:
        OmegaConf.merge(OmegaConf.structured(TrainerConfig), node)
    except OmegaConfBaseException as err:
        raise ConfigError(f"trainer.{getattr(err, 'full_key', '?')}: {str(err).splitlines()[0]}") from None
    except ValueError as err:
        raise ConfigError(str(err)) from None


def validate_config(cfg: DictConfig) -> ValidatedConfig:
    """Check every group of a composed config; raise :class:`ConfigError` naming the first bad key."""
    from hrc_lab.env import ENVS
    from hrc_lab.experiments import PROTOCOLS
    from hrc_lab.grasp import GRASPS
    from hrc_lab.motion import MOTIONS
    from hrc_lab.perception import PERCEPTIONS
    from hrc_lab.reasoning import REASONERS

    unknown = sorted(set(cfg.keys()) - TOP_LEVEL_KEYS - {"hydra"})
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown top-level key; expected one of {sorted(TOP_LEVEL_KEYS)}")
    if cfg.get("name") is None:
        raise ConfigError("name: no experiment selected; run e.g. `hrc-lab experiment=ch4/table_4_1`")
    for key, minimum in (("seed", 0), ("num_threads", 1)):
        if not isinstance(cfg.get(key), int) or cfg.get(key) < minimum:
            raise ConfigError(f"{key}: must be an integer >= {minimum}, got {cfg.get(key)!r}")
    _validate_trainer(cfg.trainer)
    reasoning = cfg.get("reasoning")
    motion = cfg.get("motion")
    perception = cfg.get("perception")
    grasp = cfg.get("grasp")
    return ValidatedConfig(
        raw=cfg,
        env=ENVS.validate(cfg.env),
        reasoning=None if reasoning is None or reasoning.get("name") == "none" else REASONERS.validate(reasoning),
        motion=None if motion is None or motion.get("name") == "none" else MOTIONS.validate(motion),
        perception=None if perception is None or perception.get("name") == "none" else PERCEPTIONS.validate(perception),
        grasp=None if grasp is None or grasp.get("name") == "none" else GRASPS.validate(grasp),
        protocol=PROTOCOLS.validate(cfg.protocol, "protocol"),
        logger=LOGGERS.validate(cfg.logger),
    )
