"""The training layer every model goes through: one Lightning ``Trainer`` built from ``conf/trainer``, with
resumable checkpoints written into the job's MLflow run.

Each fit of a job saves ``last.ckpt`` every ``trainer.checkpoint_every_n_epochs`` epochs and uploads it to the
run's artifacts under ``checkpoints/<name>/``. A job started with ``resume_from=<run id>`` continues every fit
from that run's checkpoint of the same name: fits that had finished are loaded as they ended, the interrupted one
continues from its last saved epoch. The checkpoint also holds the random number generators' states, so the
resumed job draws the same batches and ends with the same metrics as one that was never interrupted.

Every model trains as a :class:`SupervisedModule` (a network, an objective returning the loss and the values to
log, the optimizer's settings), most of them on a :class:`FixedStepDataModule` (batches drawn with replacement, a
fixed number per epoch).
"""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import numpy as np
import torch
from lightning.pytorch.callbacks import Callback, ModelCheckpoint
from torch import nn
from torch.utils.data import DataLoader, Dataset, RandomSampler, TensorDataset
from torchmetrics.functional.classification import binary_accuracy as torchmetrics_binary_accuracy
from torchmetrics.functional.classification import multiclass_accuracy

from hrc_lab.schedules import LR_SCHEDULES


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

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        """Nothing to restore: no best model is tracked, and a resumed run writes its own ``last.ckpt`` (Lightning's
        restore would warn that the folder changed, which it always does on resume)."""


class RandomState(Callback):
    """Stores the random generators' states in every checkpoint and restores them on resume, so a resumed fit
    samples the same batches and dropout masks as an uninterrupted one: torch's, NumPy's and Python's global
    generators, and the generator of the training loader's sampler when it has its own (a seeded shuffle)."""

    def __init__(self) -> None:
        self._sampler_state: torch.Tensor | None = None

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

    def on_save_checkpoint(self, trainer: pl.Trainer, pl_module: pl.LightningModule, checkpoint: dict) -> None:
        generator = _sampler_generator(trainer)
        if generator is not None:
            checkpoint["sampler_generator"] = generator.get_state()

    def on_load_checkpoint(self, trainer: pl.Trainer, pl_module: pl.LightningModule, checkpoint: dict) -> None:
        self._sampler_state = checkpoint.get("sampler_generator")  # the loader does not exist yet

    def on_train_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if self._sampler_state is not None:
            _sampler_generator(trainer).set_state(self._sampler_state)
            self._sampler_state = None


def _sampler_generator(trainer: pl.Trainer) -> torch.Generator | None:
    """The generator of the training loader's sampler (or of the loader), when it has its own."""
    loader = trainer.train_dataloader
    return getattr(getattr(loader, "sampler", None), "generator", None) or getattr(loader, "generator", None)


# --- what every model trains with ---------------------------------------------------------------------------------
# Seeding: the fits that seed (torch.manual_seed in the methods' ``fit``) seed torch's global generator, and the
# ones that do not draw their initial weights and batches from it. Lightning's Trainer keeps no generator of its own
# (``RandomState`` above saves the global ones in checkpoints), so that global state is part of a job's numbers: a
# fit that restored it afterwards (``torch.random.fork_rng``) would change what every later fit of the job draws.

Objective = Callable[[nn.Module, Any], tuple[torch.Tensor, dict[str, torch.Tensor]]]
OPTIMIZERS: dict[str, type[torch.optim.Optimizer]] = {"adam": torch.optim.Adam, "adamw": torch.optim.AdamW}


def batch_size_of(batch: Any) -> int:
    """The number of samples in a batch: graphs of a PyG batch, else the length of its first entry (a list or
    tuple of tensors, a dict of tensors)."""
    if hasattr(batch, "num_graphs"):
        return int(batch.num_graphs)
    first = next(iter(batch.values())) if isinstance(batch, dict) else batch[0]
    return len(first)


def accuracy(logits: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """The fraction of rows of ``logits`` (N, classes) whose argmax is the label (torchmetrics' micro accuracy);
    NaN for no rows (the mean of nothing, as the losses of an empty batch)."""
    if labels.numel() == 0:
        return torch.full((), float("nan"), device=logits.device)
    return multiclass_accuracy(logits, labels, num_classes=logits.shape[-1], average="micro")


def binary_accuracy(predicted: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """The fraction of the boolean ``predicted`` equal to the boolean ``truth`` (torchmetrics' binary accuracy);
    NaN when empty."""
    if truth.numel() == 0:
        return torch.full((), float("nan"), device=truth.device)
    return torchmetrics_binary_accuracy(predicted.long(), truth.long())


class SupervisedModule(pl.LightningModule):
    """Minimises ``objective(network, batch)``, which returns the loss and a dict of other values to log.

    Logs ``train_loss`` and ``train_<name>`` for every other value per epoch: the mean over the epoch's batches
    weighted by ``batch_size(batch)`` (default :func:`batch_size_of`). ``optimizer``: ``"adam"`` or ``"adamw"``,
    with ``lr`` and ``weight_decay``; ``schedule``: ``"constant"`` (``lr`` throughout) or ``"cosine"`` (a linear
    warm-up over ``warmup_steps``, at most half the fit, then a cosine decay to 0 over the fit's steps).
    :class:`ValidatedModule` also scores validation data."""

    def __init__(self, network: nn.Module, objective: Objective, lr: float, weight_decay: float = 0.0,
                 optimizer: str = "adam", batch_size: Callable[[Any], int] = batch_size_of,
                 schedule: str = "constant", warmup_steps: int = 0) -> None:
        super().__init__()
        if optimizer not in OPTIMIZERS:
            raise ValueError(f"optimizer must be one of {sorted(OPTIMIZERS)}, got {optimizer!r}")
        if schedule not in LR_SCHEDULES:
            raise ValueError(f"schedule must be one of {LR_SCHEDULES}, got {schedule!r}")
        self.network = network
        self.objective = objective
        self.lr, self.weight_decay, self.optimizer_name = lr, weight_decay, optimizer
        self.schedule, self.warmup_steps = schedule, warmup_steps
        self.batch_size_of = batch_size
        self._epoch_sums: dict[str, dict[str, torch.Tensor]] = {}  # per stage: sum of value x batch size
        self._epoch_counts: dict[str, int] = {}

    def _step(self, batch: Any, stage: str) -> torch.Tensor:
        loss, values = self.objective(self.network, batch)
        n = self.batch_size_of(batch)
        sums = self._epoch_sums.setdefault(stage, {})
        for name, value in ({"loss": loss} | values).items():
            sums[name] = sums.get(name, 0.0) + value.detach() * n
        self._epoch_counts[stage] = self._epoch_counts.get(stage, 0) + n
        return loss

    def _log_epoch_means(self, stage: str) -> None:
        """Logs the epoch's batch-size-weighted means. Accumulated here rather than by ``self.log`` at every step:
        Lightning's per-call bookkeeping cost ~1.6 ms per value, a third of a small graph model's step (measured
        with cProfile on a Fig. 4.7 job)."""
        sums, count = self._epoch_sums.pop(stage, {}), self._epoch_counts.pop(stage, 0)
        if count:
            self.log_dict({f"{stage}_{name}": total / count for name, total in sums.items()}, on_epoch=True)

    def on_train_epoch_end(self) -> None:
        self._log_epoch_means("train")

    def on_validation_epoch_end(self) -> None:
        self._log_epoch_means("val")

    def training_step(self, batch: Any, batch_idx: int) -> torch.Tensor:
        return self._step(batch, "train")

    def configure_optimizers(self):
        optimizer = OPTIMIZERS[self.optimizer_name](self.parameters(), lr=self.lr, weight_decay=self.weight_decay)
        if self.schedule == "constant":
            return optimizer
        total = max(1, int(self.trainer.estimated_stepping_batches))
        warmup = min(self.warmup_steps, total // 2)

        def factor(step: int) -> float:
            if step < warmup:
                return (step + 1) / warmup
            return 0.5 * (1 + np.cos(np.pi * min(1.0, (step - warmup) / max(1, total - warmup))))

        scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, factor)
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}


class ValidatedModule(SupervisedModule):
    """A :class:`SupervisedModule` that also logs ``val_loss`` and ``val_<name>`` per epoch on the fit's validation
    data (a separate class: Lightning warns about a ``validation_step`` without validation data)."""

    def validation_step(self, batch: Any, batch_idx: int) -> None:
        self._step(batch, "val")


class FixedStepDataModule(pl.LightningDataModule):
    """Training samples drawn with replacement, so that an epoch is ``steps_per_epoch`` batches of ``batch_size``
    whatever the data set's size (the experiments train on a dozen to thousands of samples).

    ``samples``: a map-style dataset (e.g. a ``TensorDataset`` of input and target tensors; items batched by
    ``collate_fn``, torch's default collation when None) or a list of PyG graphs (batched as PyG collates them,
    by :class:`GraphBank`).
    ``generator`` draws the samples; when None, ``RandomSampler`` takes a seed from torch's global generator at
    every epoch."""

    def __init__(self, samples: Dataset | Sequence, batch_size: int, steps_per_epoch: int,
                 generator: torch.Generator | None = None, collate_fn: Callable | None = None) -> None:
        super().__init__()
        if len(samples) == 0:
            raise ValueError("no training samples")
        self.samples = samples
        self.batch_size = batch_size
        self.steps_per_epoch = steps_per_epoch
        self.generator = generator
        self.collate_fn = collate_fn

    def train_dataloader(self) -> DataLoader:
        sampler = RandomSampler(self.samples, replacement=True, num_samples=self.batch_size * self.steps_per_epoch,
                                generator=self.generator)
        if _holds_graphs(self.samples):
            bank = GraphBank(self.samples)
            return DataLoader(range(len(self.samples)), batch_size=self.batch_size, sampler=sampler,
                              collate_fn=bank.batch)
        return DataLoader(self.samples, batch_size=self.batch_size, sampler=sampler, collate_fn=self.collate_fn)


class GraphBank:
    """PyG graphs collated once; ``batch(indices)`` is the mini-batch of the graphs at ``indices``, equal tensor for
    tensor to ``Batch.from_data_list([graphs[i] for i in indices])``, gathered with index arithmetic on the collated
    bank instead of PyG's per-graph collation (5 ms -> 2 ms of a 15-ms step of Ch.4's reasoning models at 64 graphs,
    measured). Graphs are read once: a PyG dataset's random transform would not be redrawn per batch."""

    def __init__(self, graphs: Sequence) -> None:
        from torch_geometric.data import Batch

        graphs = list(graphs)
        self.bank = Batch.from_data_list(graphs)
        self.n_nodes = self.bank.ptr.diff()
        self.keys = [key for key in self.bank.keys() if key not in ("batch", "ptr", "num_nodes")]
        # per tensor attribute: its concatenation dim, each graph's start and size along it, and, for attributes
        # PyG increments (edge_index: by each graph's node count), each graph's increment and its offset in the bank
        self.layout: dict[str, tuple[int, torch.Tensor, torch.Tensor, torch.Tensor | None, torch.Tensor | None]] = {}
        first = graphs[0]
        for key in self.keys:
            if not isinstance(first[key], torch.Tensor):
                continue  # collated to a list (strings, lists) or a tensor of numbers: one entry per graph
            cat_dim = first.__cat_dim__(key, first[key])
            dim = 0 if cat_dim is None or first[key].dim() == 0 else cat_dim % self.bank[key].dim()
            bounds = self.bank._slice_dict[key]
            increments = torch.tensor([graph.__inc__(key, graph[key]) for graph in graphs])
            if not increments.any():
                self.layout[key] = (dim, bounds[:-1], bounds.diff(), None, None)
                continue
            self.layout[key] = (dim, bounds[:-1], bounds.diff(), increments, _exclusive_cumsum(increments))

    def batch(self, indices: Sequence[int]):
        from torch_geometric.data import Batch

        index = torch.as_tensor(indices, dtype=torch.long)
        values, slices, incs = {}, {}, {}
        for key in self.keys:
            value = self.bank[key]
            if key not in self.layout:
                values[key] = value[index] if isinstance(value, torch.Tensor) else [value[i] for i in index.tolist()]
                continue
            dim, starts, sizes, increments, offsets = self.layout[key]
            sizes = sizes[index]
            before = _exclusive_cumsum(sizes)
            positions = torch.arange(int(sizes.sum())) + torch.repeat_interleave(starts[index] - before, sizes)
            picked = value.index_select(dim, positions)
            slices[key] = torch.cat([before, sizes.sum().view(1)])
            incs[key] = torch.zeros(len(index), dtype=torch.long)
            if increments is not None:
                incs[key] = _exclusive_cumsum(increments[index])
                shift = torch.repeat_interleave(incs[key] - offsets[index], sizes)
                picked = picked + shift.view([-1 if d == dim else 1 for d in range(picked.dim())])
            values[key] = picked
        n_nodes = self.n_nodes[index]
        out = Batch(**values)
        out.num_nodes = int(n_nodes.sum())
        out.batch = torch.repeat_interleave(torch.arange(len(index)), n_nodes)
        out.ptr = torch.cat([_exclusive_cumsum(n_nodes), n_nodes.sum().view(1)])
        out._num_graphs, out._slice_dict, out._inc_dict = len(index), slices, incs
        return out


def _exclusive_cumsum(values: torch.Tensor) -> torch.Tensor:
    """[0, v0, v0 + v1, ...] without the total."""
    return torch.cumsum(values, 0) - values


def _holds_graphs(samples: Dataset | Sequence) -> bool:
    """Whether ``samples`` are PyG graphs (a list of them or a PyG dataset), found without importing PyG and
    without reading a dataset's item (which may draw a random augmentation)."""
    if isinstance(samples, Dataset):
        return any(c.__module__.startswith("torch_geometric.") for c in type(samples).__mro__)
    return type(samples[0]).__module__.startswith("torch_geometric.")


def steps_per_epoch(total_steps: int, trainer: pl.Trainer) -> int:
    """``total_steps`` gradient steps split over the Trainer's ``max_epochs`` (at least one per epoch)."""
    epochs = trainer.max_epochs if trainer.max_epochs and trainer.max_epochs > 0 else 1
    return max(1, total_steps // epochs)


def fit_tensors(network: nn.Module, objective: Objective, tensors: Sequence[torch.Tensor], lr: float, steps: int,
                batch_size: int, trainer_factory: Callable[[], pl.Trainer]) -> nn.Module:
    """Train ``network`` on the rows of ``tensors`` (inputs and targets, one batch of each is the objective's
    ``batch``) for about ``steps`` gradient steps with Adam; ``trainer_factory()`` builds the Trainer (from
    ``conf/trainer``, logging into the job's MLflow run). Returns the network in eval mode."""
    trainer = trainer_factory()
    data = FixedStepDataModule(TensorDataset(*tensors), batch_size, steps_per_epoch(steps, trainer))
    trainer.fit(SupervisedModule(network, objective, lr), datamodule=data)
    return network.eval()
