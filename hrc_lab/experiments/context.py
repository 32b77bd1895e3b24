"""What a protocol receives from its Hydra job."""

from __future__ import annotations

from dataclasses import dataclass

import lightning.pytorch as pl
import numpy as np
from hydra.utils import instantiate

from hrc_lab.config import ValidatedConfig
from hrc_lab.tracking import RunTracker


@dataclass
class RunContext:
    """The validated config, the job's MLflow run and its seed."""

    cfg: ValidatedConfig
    tracker: RunTracker
    seed: int

    def rng(self, *stream: int) -> np.random.Generator:
        """An independent, reproducible random stream per purpose (data, folds, test scenarios...)."""
        return np.random.default_rng([self.seed, *stream])

    def trainer(self, prefix: str = "", **overrides) -> pl.Trainer:
        """A Lightning Trainer from ``conf/trainer`` (``overrides`` replace its keys, e.g. ``max_epochs``) logging
        per-epoch metrics into this run under ``prefix``."""
        return instantiate(
            self.cfg.raw.trainer, logger=self.tracker.lightning_logger(prefix), _convert_="all", **overrides
        )
