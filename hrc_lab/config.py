"""Validation of a composed config before any work starts (light: imports no torch, lightning or mlflow).

Hydra already refuses command-line overrides of keys that do not exist (struct mode); this module checks what
the YAML files and ``+key=`` additions may still get wrong: unknown keys, wrong types and impossible values in
every group, naming the full key in the error (``env.n_selected``, ``reasoning.hiden``, ``trainer.max_epoch``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from hydra.core.config_store import ConfigStore
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
    "resume_from",
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
    """The Lightning ``Trainer`` arguments a run may set, with their defaults (written here only: the files in
    ``conf/trainer`` name what differs). One epoch is ``steps_per_epoch`` batches of the module being trained, so
    ``max_epochs`` fixes the training length; add an argument here to expose it."""

    accelerator: str = "cpu"
    devices: Any = 1
    strategy: str = "auto"
    num_nodes: int = 1
    precision: Any = "32-true"
    max_epochs: int = 20
    max_steps: int = -1
    deterministic: bool = True
    log_every_n_steps: int = 50
    enable_progress_bar: bool = False  # sweeps run hundreds of short fits; each job's tqdm bar shows progress
    enable_model_summary: bool = False
    enable_checkpointing: bool = True
    gradient_clip_val: float | None = None
    default_root_dir: str | None = None
    # hrc_lab's own key (not passed to the Trainer): save a resumable checkpoint every n epochs
    checkpoint_every_n_epochs: int = 1

    def __post_init__(self) -> None:
        # Lightning reads max_epochs=-1 as "train forever": rejected, every run here has a finite length.
        if self.max_epochs < 1:
            raise ValueError(f"trainer.max_epochs must be >= 1, got {self.max_epochs}")
        if self.max_steps != -1 and self.max_steps < 1:
            raise ValueError(f"trainer.max_steps must be >= 1 (or -1: bounded by max_epochs), got {self.max_steps}")
        if self.log_every_n_steps < 1:
            raise ValueError(f"trainer.log_every_n_steps must be >= 1, got {self.log_every_n_steps}")
        if self.checkpoint_every_n_epochs < 1:
            raise ValueError(f"trainer.checkpoint_every_n_epochs must be >= 1, got {self.checkpoint_every_n_epochs}")
        if self.gradient_clip_val is not None and self.gradient_clip_val <= 0:
            raise ValueError(f"trainer.gradient_clip_val must be > 0 or null, got {self.gradient_clip_val}")


# conf/trainer/*.yaml extend this schema (defaults: [schema]), so Hydra knows every key a user may override.
ConfigStore.instance().store(group="trainer", name="schema", node=TrainerConfig)


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
    trainer: TrainerConfig
    resume_from: str | None = None


def _validate_trainer(node: DictConfig) -> TrainerConfig:
    """The user's merged trainer values as a :class:`TrainerConfig` (so its checks run on them, not on defaults)."""
    try:
        values = OmegaConf.to_container(node, resolve=True)
        return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(TrainerConfig), values))
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
    trainer = _validate_trainer(cfg.trainer)
    resume_from = cfg.get("resume_from")
    if resume_from is not None and not (isinstance(resume_from, str) and re.fullmatch(r"[0-9a-f]{32}", resume_from)):
        raise ConfigError(f"resume_from: must be the 32-character id of an MLflow run, got {resume_from!r}")
    reasoning = cfg.get("reasoning")
    motion = cfg.get("motion")
    perception = cfg.get("perception")
    grasp = cfg.get("grasp")
    validated = ValidatedConfig(
        raw=cfg,
        env=ENVS.validate(cfg.env),
        reasoning=None if reasoning is None or reasoning.get("name") == "none" else REASONERS.validate(reasoning),
        motion=None if motion is None or motion.get("name") == "none" else MOTIONS.validate(motion),
        perception=None if perception is None or perception.get("name") == "none" else PERCEPTIONS.validate(perception),
        grasp=None if grasp is None or grasp.get("name") == "none" else GRASPS.validate(grasp),
        protocol=PROTOCOLS.validate(cfg.protocol, "protocol"),
        logger=LOGGERS.validate(cfg.logger),
        trainer=trainer,
        resume_from=resume_from,
    )
    _check_across_groups(validated)
    return validated


def _check_across_groups(validated: ValidatedConfig) -> None:
    """Checks that relate two groups: a protocol schema may define ``check(validated)``, raising ``ValueError``
    (or :class:`ConfigError`) that names the keys, e.g. ``protocol.object_counts`` against ``env.max_counts``."""
    check = getattr(validated.protocol, "check", None)
    if check is None:
        return
    try:
        check(validated)
    except ConfigError:
        raise
    except ValueError as err:
        raise ConfigError(str(err)) from None
