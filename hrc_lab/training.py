"""The training layer every model goes through: one Lightning ``Trainer`` built from ``conf/trainer``, with
resumable checkpoints written into the job's MLflow run.

Each fit of a job saves ``last.ckpt`` every ``trainer.checkpoint_every_n_epochs`` epochs and uploads it to the
run's artifacts under ``checkpoints/<name>/``. A job started with ``resume_from=<run id>`` continues every fit
from that run's checkpoint of the same name: fits that had finished are loaded as they ended, the interrupted one
continues from its last saved epoch. The checkpoint also holds the random number generators' states, so the
resumed job draws the same batches and ends with the same metrics as one that was never interrupted.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import numpy as np
import torch
from lightning.pytorch.callbacks import Callback, ModelCheckpoint


class Trainer(pl.Trainer):
    """Lightning's Trainer whose ``fit`` continues from ``resume_checkpoint`` when one is given."""

    def __init__(self, *args, resume_checkpoint: str | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.resume_checkpoint = resume_checkpoint

    def fit(self, model, train_dataloaders=None, val_dataloaders=None, datamodule=None, ckpt_path=None,
            weights_only=None) -> None:
        # weights_only=False: a Lightning checkpoint holds loop and callback states besides tensors; it is only
        # ever read from this job's own MLflow run (or the run it resumes).
        if ckpt_path is None and self.resume_checkpoint is not None:
            ckpt_path, weights_only = self.resume_checkpoint, False
        super().fit(model, train_dataloaders, val_dataloaders, datamodule, ckpt_path, weights_only)


class RunCheckpoint(ModelCheckpoint):
    """``last.ckpt`` every ``every_n_epochs`` epochs and after the last one, each copy uploaded to the run.
    (A ModelCheckpoint, so Lightning adds no default checkpoint of its own.)"""

    def __init__(self, dirpath: Path, every_n_epochs: int, upload: Callable[[Path], None]) -> None:
        super().__init__(dirpath=dirpath, save_top_k=0, save_last=True, every_n_epochs=every_n_epochs,
                         enable_version_counter=False)
        self.upload = upload

    def on_train_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        epochs_done = trainer.current_epoch + 1
        due = epochs_done % self._every_n_epochs == 0 or epochs_done >= (trainer.max_epochs or 0)
        if due and not self._should_skip_saving_checkpoint(trainer):
            self._save_last_checkpoint(trainer, self._monitor_candidates(trainer))

    def on_validation_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        """Checkpoints follow training epochs only (Lightning's default would also save after validation)."""

    def _save_checkpoint(self, trainer: pl.Trainer, filepath: str) -> None:
        super()._save_checkpoint(trainer, filepath)
        self.upload(Path(filepath))


class RandomState(Callback):
    """Stores torch's, NumPy's and Python's global generator states in every checkpoint and restores them on
    resume, so a resumed fit samples the same batches (``RandomSampler``) and dropout masks."""

    def state_dict(self) -> dict[str, Any]:
        kind, keys, pos, has_gauss, cached = np.random.get_state()
        return {
            "torch": torch.get_rng_state(),
            "numpy": (kind, torch.from_numpy(keys.astype(np.int64)), pos, has_gauss, cached),
            "python": random.getstate(),
        }

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        torch.set_rng_state(state_dict["torch"])
        kind, keys, pos, has_gauss, cached = state_dict["numpy"]
        np.random.set_state((kind, keys.numpy().astype(np.uint32), pos, has_gauss, cached))
        random.setstate(state_dict["python"])
