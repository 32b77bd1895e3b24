"""What a protocol receives from its Hydra job."""

from __future__ import annotations

import dataclasses
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hrc_lab.config import ValidatedConfig
from hrc_lab.tracking import RunTracker
from hrc_lab.training import RandomState, RunCheckpoint, Trainer


def trainer_settings(trainer_cfg) -> tuple[dict, int]:
    """``conf/trainer`` as Lightning Trainer keyword arguments, and its checkpoint interval in epochs (a key of ours,
    not the Trainer's)."""
    settings = dataclasses.asdict(trainer_cfg)
    return settings, settings.pop("checkpoint_every_n_epochs")


def unlogged_trainer(trainer_cfg):
    """A Trainer factory with :meth:`RunContext.trainer`'s signature and ``conf/trainer`` settings that logs and
    checkpoints nothing: for scripts that re-train a finished run's models outside any run."""
    settings, _ = trainer_settings(trainer_cfg)
    return lambda prefix="", **overrides: Trainer(**{**settings, **overrides, "enable_checkpointing": False,
                                                     "logger": False})


@dataclass
class RunContext:
    """The validated config, the job's MLflow run, its seed and its output folder."""

    cfg: ValidatedConfig
    tracker: RunTracker
    seed: int
    output_dir: Path
    _fits: Counter = field(default_factory=Counter)

    def rng(self, *stream: int) -> np.random.Generator:
        """An independent, reproducible random stream per purpose (data, folds, test scenarios...)."""
        return np.random.default_rng([self.seed, *stream])

    def trainer(self, prefix: str = "", **overrides) -> Trainer:
        """A Lightning Trainer from ``conf/trainer`` (``overrides`` replace its keys, e.g. ``max_epochs``) logging
        per-epoch metrics into this run under ``prefix`` and checkpointing into its artifacts
        (``checkpoints/<prefix>``; a prefix used twice in a job gets ``-2``, ``-3``... in the order of the fits).
        With ``resume_from`` set, the fit continues from that run's checkpoint of the same name."""
        name = prefix.strip("/") or "model"
        self._fits[name] += 1
        if self._fits[name] > 1:
            name = f"{name}-{self._fits[name]}"
        folder = f"checkpoints/{name}"
        settings, every_n_epochs = trainer_settings(self.cfg.trainer)
        callbacks = [RandomState()]
        if settings["enable_checkpointing"]:
            upload = lambda path: self.tracker.log_artifact(path, folder)  # noqa: E731
            callbacks.append(RunCheckpoint(self.output_dir / folder, every_n_epochs, upload))
        resume = self.tracker.resume_checkpoint(f"{folder}/last.ckpt") if self.cfg.resume_from else None
        if resume is not None:
            self.tracker.log_artifact(resume, folder)  # the new run holds every checkpoint it continues from
        return Trainer(**{**settings, **overrides}, logger=self.tracker.lightning_logger(prefix),
                       callbacks=callbacks, resume_checkpoint=resume)

    def resume_agent(self, folder: str, env):
        """With ``resume_from``: the RL agent saved under ``folder`` of the killed run (or of the run it resumed, when
        it saved none; :meth:`~hrc_lab.tracking.RunTracker.resume_checkpoint`), with whichever of its buffers were
        saved beside it, on ``env`` (:func:`~hrc_lab.rl.agent.load_agent`); None without ``resume_from`` or when no
        run of that chain saved one."""
        from hrc_lab.rl.agent import AGENT_FILE, BUFFER_FILE, DEMO_BUFFER_FILE, load_agent

        if not self.cfg.resume_from:
            return None
        saved = self.tracker.resume_checkpoint(f"{folder}/{AGENT_FILE}")
        if saved is None:
            return None
        for name in (BUFFER_FILE, DEMO_BUFFER_FILE):  # into the same folder, when they exist
            self.tracker.resume_checkpoint(f"{folder}/{name}")
        return load_agent(saved.parent, env)
