"""Validation of a composed config before any work starts (light: imports no torch, lightning or mlflow).

Hydra already refuses command-line overrides of keys that do not exist (struct mode); this module checks what
the YAML files and ``+key=`` additions may still get wrong: unknown keys, wrong types and impossible values in
every group, naming the full key in the error (``env.n_selected``, ``reasoning.hiden``, ``trainer.max_epoch``).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig

from hrc_lab.registry import ConfigError, Registry, typed

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
    "rl",
    "tamp",
    "trainer",
    "logger",
    "paths",
    "resume_from",
    "search",
}


@dataclass
class LoggerConfig:
    """MLflow tracking (``conf/logger/mlflow.yaml`` holds the values: they follow ``paths.runs_dir``)."""

    tracking_uri: str
    artifact_root: str  # where new MLflow experiments keep artifacts (local stores)

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
    ``conf/trainer`` name what differs). A fixed-step model trains its group's ``steps`` split into ``max_epochs``
    epochs (``hrc_lab.training.steps_per_epoch``), so ``max_epochs`` sets how often metrics are logged and
    checkpoints saved; the Ch.5 action detector trains ``max_epochs`` full passes. ``max_steps`` caps every fit.
    Add an argument here to expose it."""

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


@dataclass
class PathsConfig:
    runs_dir: str  # everything a run writes (MLflow store, Hydra outputs, caches, data sets); conf/paths


def runs_dir() -> Path:
    """``paths.runs_dir`` for the console scripts that run outside a Hydra job (``hrc-lab-server``,
    ``hrc-lab-reproduce``): ``$HRC_LAB_RUNS``, else ``runs``, the rule of ``conf/paths/default.yaml``."""
    return Path(os.environ.get("HRC_LAB_RUNS", "runs"))


def default_tracking_uri() -> str:
    """The MLflow store a job logs to by default (``conf/logger/mlflow.yaml``: the sqlite file under
    :func:`runs_dir`), for the console scripts that read it (``hrc-lab-report``, ``hrc-lab-runs``)."""
    return f"sqlite:///{runs_dir()}/mlflow.db"


def group_registries() -> dict[str, Registry]:
    """The registry of every config group that selects an implementation by ``name``."""
    from hrc_lab.env import ENVS
    from hrc_lab.grasp import GRASPS
    from hrc_lab.motion import MOTIONS
    from hrc_lab.perception import PERCEPTIONS
    from hrc_lab.reasoning import REASONERS
    from hrc_lab.rl import RLS
    from hrc_lab.tamp import TAMPS

    return {"env": ENVS, "reasoning": REASONERS, "motion": MOTIONS, "perception": PERCEPTIONS, "grasp": GRASPS,
            "rl": RLS, "tamp": TAMPS, "logger": LOGGERS}


def register_schemas() -> None:
    """Give Hydra every group's schema before it composes a config, so each ``conf/<group>/*.yaml`` extends its
    schema and names only what differs (``schema/<group>/<name>``; the trainer's as ``trainer/schema``; each
    experiment file's ``protocol`` extends ``schema/protocol/<name>``). Called when :mod:`hrc_lab.cli` is imported
    (also in a launcher's worker processes) and by the tests."""
    from hrc_lab.experiments import PROTOCOLS

    ConfigStore.instance().store(group="trainer", name="schema", node=TrainerConfig)
    for registry in (*group_registries().values(), PROTOCOLS):
        registry.store_schemas()


@dataclass
class ValidatedConfig:
    """The typed view of a run's config that protocols receive: one validated config per group (each keeps its
    ``name``; None for a group set to ``none``). ``raw`` keeps the composed DictConfig for logging."""

    raw: DictConfig
    env: Any
    reasoning: Any
    motion: Any
    perception: Any
    grasp: Any
    rl: Any
    tamp: Any
    protocol: Any
    logger: LoggerConfig
    trainer: TrainerConfig
    paths: PathsConfig
    resume_from: str | None = None


def validate_config(cfg: DictConfig) -> ValidatedConfig:
    """Check every group of a composed config; raise :class:`ConfigError` naming the first bad key."""
    from hrc_lab.experiments import PROTOCOLS

    registries = group_registries()
    unknown = sorted(set(cfg.keys()) - TOP_LEVEL_KEYS - {"hydra"})
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown top-level key; expected one of {sorted(TOP_LEVEL_KEYS)}")
    if cfg.get("name") is None:
        raise ConfigError("name: no experiment selected; run e.g. `hrc-lab experiment=ch4/table_4_1`")
    for key, minimum in (("seed", 0), ("num_threads", 1)):
        if not isinstance(cfg.get(key), int) or cfg.get(key) < minimum:
            raise ConfigError(f"{key}: must be an integer >= {minimum}, got {cfg.get(key)!r}")
    search = cfg.get("search") or {}
    unknown = sorted(set(search.keys()) - {"name", "objective"})  # conf/search/*.yaml (hrc_lab.search.SEARCH_KEYS)
    if unknown:
        raise ConfigError(f"search.{unknown[0]}: unknown key; expected name, objective")
    trainer = typed(TrainerConfig, cfg.trainer, "trainer")
    _check_combination(cfg)
    resume_from = cfg.get("resume_from")
    if resume_from is not None and not (isinstance(resume_from, str) and re.fullmatch(r"[0-9a-f]{32}", resume_from)):
        raise ConfigError(f"resume_from: must be the 32-character id of an MLflow run, got {resume_from!r}")
    modules = {}
    for group in ("reasoning", "motion", "perception", "grasp", "rl", "tamp"):
        node = cfg.get(group)
        modules[group] = None if node is None or node.get("name") == "none" else registries[group].validate(node)
    validated = ValidatedConfig(
        raw=cfg,
        env=registries["env"].validate(cfg.env),
        **modules,
        protocol=PROTOCOLS.validate(cfg.protocol, "protocol"),
        logger=LOGGERS.validate(cfg.logger),
        trainer=trainer,
        paths=typed(PathsConfig, cfg.paths, "paths"),
        resume_from=resume_from,
    )
    _check_across_groups(validated)
    return validated


def _check_combination(cfg: DictConfig) -> None:
    """The protocol runs with this env and these modules (``ACCEPTS`` in :mod:`hrc_lab.experiments.schemas`);
    checked on the names before any group is validated, so a wrong group is named as such."""
    from hrc_lab.experiments.schemas import ACCEPTS, GROUPS, check_combination

    protocol = (cfg.get("protocol") or {}).get("name")
    if protocol not in ACCEPTS:
        return  # PROTOCOLS.validate names the problem
    names = {group: (cfg.get(group) or {}).get("name", "none") for group in GROUPS}
    try:
        check_combination(protocol, names)
    except ValueError as err:
        raise ConfigError(str(err)) from None


def _check_across_groups(validated: ValidatedConfig) -> None:
    """The protocol schema's own ``check(validated)``, relating its values to other groups' (e.g.
    ``protocol.object_counts`` against ``env.max_counts``). A ``ValueError`` becomes a :class:`ConfigError`."""
    check = getattr(validated.protocol, "check", None)
    if check is None:
        return
    try:
        check(validated)
    except ConfigError:
        raise
    except ValueError as err:
        raise ConfigError(str(err)) from None


register_schemas()  # on import: Hydra composes nothing of hrc_lab's before this module is loaded
