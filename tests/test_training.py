"""The training layer (hrc_lab.training): the supervised LightningModule every model trains as and the fixed-step
data module: batch shapes, a fixed number of steps per epoch whatever the data size, the sampler's draws, logged
keys, the optimizer settings, and a learning test."""

from __future__ import annotations

import lightning.pytorch as pl
import pytest
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader, RandomSampler, TensorDataset
from torch_geometric.data import Batch, Data

from hrc_lab.training import (
    FixedStepDataModule,
    GraphBank,
    SupervisedModule,
    ValidatedModule,
    accuracy,
    batch_size_of,
    binary_accuracy,
    fit_tensors,
    steps_per_epoch,
)


def tiny_trainer(max_epochs: int) -> pl.Trainer:
    return pl.Trainer(max_epochs=max_epochs, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                      enable_model_summary=False, accelerator="cpu", deterministic=True)


def classification(objective_values: bool = True):
    """Cross-entropy on (inputs, labels) batches, with the accuracy as the value to log."""

    def objective(network, batch):
        x, y = batch
        logits = network(x)
        return F.cross_entropy(logits, y), ({"acc": accuracy(logits, y)} if objective_values else {})

    return objective


def blobs(n: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Two Gaussian blobs in 2-D, centres (-2, 0) and (2, 0): a linear classifier gets nearly all right."""
    generator = torch.Generator().manual_seed(seed)
    labels = torch.randint(0, 2, (n,), generator=generator)
    x = torch.randn(n, 2, generator=generator) + torch.stack([4.0 * labels - 2, torch.zeros(n)], dim=1)
    return x, labels


@pytest.mark.parametrize("n_samples", [5, 1000])
def test_an_epoch_is_steps_per_epoch_full_batches_whatever_the_data_size(n_samples):
    data = FixedStepDataModule(TensorDataset(torch.randn(n_samples, 3), torch.arange(n_samples)), 4, 7)
    batches = list(data.train_dataloader())
    assert len(batches) == 7
    assert all(x.shape == (4, 3) and y.shape == (4,) for x, y in batches)
    assert all(0 <= i < n_samples for _, y in batches for i in y.tolist())


def test_graph_samples_are_batched_by_pyg():
    no_edges = torch.zeros(2, 0, dtype=torch.long)
    graphs = [Data(x=torch.full((k + 1, 2), float(k)), edge_index=no_edges, y=torch.tensor([k])) for k in range(3)]
    batches = list(FixedStepDataModule(graphs, 5, 2).train_dataloader())
    assert len(batches) == 2
    for batch in batches:
        assert batch.num_graphs == 5 and batch.y.shape == (5,) and batch_size_of(batch) == 5
        assert batch.x.shape[0] == int((batch.y + 1).sum())  # each graph keeps its own nodes


def test_a_graph_bank_batch_is_what_pyg_collates():
    """Node, edge and graph attributes, edge indices shifted by the node counts, empty graphs, 0-dim tensors, ints
    and lists: every attribute of a bank's batch equals PyG's collation of the same graphs (repeats included)."""
    generator = torch.Generator().manual_seed(0)
    graphs = []
    for i in range(12):
        n = i % 4  # graphs 0, 4, 8 have no nodes
        graphs.append(Data(x=torch.randn(n, 3, generator=generator), num_nodes=n,
                           edge_index=torch.randint(0, max(n, 1), (2, 2 * n), generator=generator),
                           pair=torch.randint(0, 4, (n, 2), generator=generator), label=torch.tensor([i]),
                           goals=torch.randn(1, 4, 3, generator=generator), weight=torch.tensor(0.5 * i),
                           count=i, names=[f"part{i}"]))
    bank = GraphBank(graphs)
    for indices in ([3, 3, 7, 0, 11], [5], list(range(12)), [8, 1, 2]):
        ours, pyg = bank.batch(indices), Batch.from_data_list([graphs[i] for i in indices])
        assert sorted(ours.keys()) == sorted(pyg.keys())
        for key in pyg.keys():
            if isinstance(pyg[key], torch.Tensor):
                assert ours[key].dtype == pyg[key].dtype and torch.equal(ours[key], pyg[key]), key
            else:
                assert ours[key] == pyg[key], key
        assert (ours.num_graphs, ours.num_nodes) == (pyg.num_graphs, pyg.num_nodes)
        assert [g.x.shape[0] for g in ours.to_data_list()] == [graphs[i].x.shape[0] for i in indices]


def test_draws_are_those_of_a_random_sampler_with_replacement():
    """The module must draw what the experiments drew before it existed: a DataLoader over RandomSampler(
    replacement=True) seeded from torch's global generator, or from the given generator."""
    n, batch_size, steps = 11, 4, 5
    dataset = TensorDataset(torch.arange(n))
    torch.manual_seed(3)
    drawn = torch.cat([b[0] for b in FixedStepDataModule(dataset, batch_size, steps).train_dataloader()]).tolist()
    after = torch.rand(1)
    torch.manual_seed(3)
    sampler = RandomSampler(dataset, replacement=True, num_samples=batch_size * steps)
    expected = torch.cat([b[0] for b in DataLoader(dataset, batch_size=batch_size, sampler=sampler)]).tolist()
    assert drawn == expected and torch.equal(after, torch.rand(1))

    def seeded():
        data = FixedStepDataModule(dataset, batch_size, steps, generator=torch.Generator().manual_seed(7))
        return torch.cat([b[0] for b in data.train_dataloader()]).tolist()

    torch.manual_seed(0)
    first = seeded()
    torch.manual_seed(1)
    assert seeded() == first  # a generator of its own: the global state plays no part


def test_no_samples_is_an_error():
    with pytest.raises(ValueError, match="no training samples"):
        FixedStepDataModule([], 4, 2)
    with pytest.raises(ValueError, match="no training samples"):
        FixedStepDataModule(TensorDataset(torch.zeros(0, 3)), 4, 2)


def test_batch_sizes_and_steps_per_epoch():
    assert batch_size_of([torch.zeros(6, 2), torch.zeros(6)]) == 6
    assert batch_size_of({"track": torch.zeros(3, 4), "label": torch.zeros(3)}) == 3
    assert steps_per_epoch(100, tiny_trainer(3)) == 33
    assert steps_per_epoch(2, tiny_trainer(5)) == 1  # at least one


def test_accuracy_is_the_fraction_of_right_argmaxes():
    logits = torch.tensor([[2.0, 1.0, 0.0], [0.0, 1.0, 3.0], [1.0, 0.0, 0.0], [0.0, 5.0, 1.0]])
    labels = torch.tensor([0, 2, 1, 0])
    assert accuracy(logits, labels).item() == pytest.approx(0.5)
    assert torch.equal(accuracy(logits, labels), (logits.argmax(-1) == labels).float().mean())
    predicted, truth = torch.tensor([True, False, True]), torch.tensor([True, True, True])
    assert binary_accuracy(predicted, truth).item() == pytest.approx(2 / 3)
    # no samples (a batch without labelled nodes): NaN, the mean of nothing, as before torchmetrics computed it
    assert accuracy(logits[:0], labels[:0]).isnan() and binary_accuracy(torch.zeros(0) > 0, torch.zeros(0) > 0).isnan()


def test_optimizer_settings():
    network = torch.nn.Linear(2, 2)
    adam = SupervisedModule(network, classification(), lr=0.01).configure_optimizers()
    assert type(adam) is torch.optim.Adam and adam.defaults["lr"] == 0.01 and adam.defaults["weight_decay"] == 0
    adamw = SupervisedModule(network, classification(), 0.02, weight_decay=0.1, optimizer="adamw")
    adamw = adamw.configure_optimizers()
    assert type(adamw) is torch.optim.AdamW and adamw.defaults["weight_decay"] == 0.1
    with pytest.raises(ValueError, match="optimizer"):
        SupervisedModule(network, classification(), 0.01, optimizer="sgd")


def test_a_fit_is_max_epochs_times_steps_per_epoch_steps_and_logs_per_stage():
    torch.manual_seed(0)
    x, y = blobs(40, seed=0)
    trainer = tiny_trainer(3)
    module = ValidatedModule(torch.nn.Linear(2, 2), classification(), lr=0.05)
    val = DataLoader(TensorDataset(*blobs(20, seed=1)), batch_size=8)
    trainer.fit(module, train_dataloaders=FixedStepDataModule(TensorDataset(x, y), 8, 4).train_dataloader(),
                val_dataloaders=val)
    assert trainer.global_step == 3 * 4
    assert {"train_loss", "train_acc", "val_loss", "val_acc"} <= set(trainer.callback_metrics)
    # the epoch's value is the mean over its samples (batches of 8, 8 and 4 weighted by size), without the
    # sanity-check batches Lightning scores before training
    with torch.no_grad():
        x_val, y_val = blobs(20, seed=1)
        logits = module.network(x_val)
    assert trainer.callback_metrics["val_loss"].item() == pytest.approx(F.cross_entropy(logits, y_val).item())
    assert trainer.callback_metrics["val_acc"].item() == pytest.approx(accuracy(logits, y_val).item())


def test_a_linear_classifier_learns_two_blobs():
    """Through fit_tensors (the motion models' path): few enough steps that a broken optimizer, objective or data
    module leaves the accuracy near chance, which this would catch."""
    torch.manual_seed(0)
    network = torch.nn.Linear(2, 2)
    x, y = blobs(200, seed=0)
    test_x, test_y = blobs(200, seed=1)
    before = accuracy(network(test_x), test_y).item()
    fit_tensors(network, classification(), [x, y], lr=0.05, steps=60, batch_size=16,
                trainer_factory=lambda: tiny_trainer(2))
    assert not network.training
    with torch.no_grad():
        after = accuracy(network(test_x), test_y).item()
    assert after > 0.95 and after > before


def test_an_unlogged_trainer_has_the_configs_settings_and_neither_logger_nor_checkpoints():
    """The factory scripts use to re-train a finished run's models: conf/trainer's settings and overrides, as
    RunContext.trainer, without writing into any run."""
    from hrc_lab.config import TrainerConfig
    from hrc_lab.run_context import trainer_settings, unlogged_trainer

    settings, every_n_epochs = trainer_settings(TrainerConfig(max_epochs=7))
    assert settings["max_epochs"] == 7 and "checkpoint_every_n_epochs" not in settings
    assert every_n_epochs == TrainerConfig().checkpoint_every_n_epochs
    trainer = unlogged_trainer(TrainerConfig(max_epochs=7))("subgoal", max_epochs=3)
    assert trainer.max_epochs == 3 and trainer.logger is None and trainer.checkpoint_callback is None
