import numpy as np
import pytest
import torch
from torch_geometric.loader import DataLoader

from hrc_lab.env.robot.spec import PackageToOrderSpec, goal_configurations, sample_episode, stage_observations
from hrc_lab.experiments.ch4_reasoning import evaluate
from hrc_lab.reasoning import REASONERS
from hrc_lab.reasoning.module import ReasoningModule

SPEC = PackageToOrderSpec(n_objects=5, n_selected=4)
TORCH_METHODS = ["ours", "gnn", "gnn_task", "mlp"]


def demos(n_configurations=12, seed=0):
    rng = np.random.default_rng(seed)
    configurations = goal_configurations(SPEC)[:n_configurations]
    return [sample_episode(SPEC, c, rng) for c in configurations]


def observations(episodes):
    return [o for e in episodes for o in stage_observations(e)]


@pytest.mark.parametrize("method", TORCH_METHODS)
def test_output_shapes(method):
    reasoner = REASONERS.build(REASONERS.validate({"name": method}), spec=SPEC)
    batch = next(iter(DataLoader([reasoner.encode(o) for o in observations(demos(3))], batch_size=24)))
    logits_o, logits_g = reasoner.network(batch, teacher_forcing=False)
    assert logits_o.shape == (24, SPEC.n_objects + 1)  # P_o: packaging area + m products
    assert logits_g.shape == (24, SPEC.slots + 1)  # P_g: picking stage + n goal slots
    assert reasoner.predict(observations(demos(1))).shape == (8, 2)


@pytest.mark.parametrize("method", TORCH_METHODS)
def test_joint_loss_falls_on_a_tiny_batch(method):
    torch.manual_seed(0)
    reasoner = REASONERS.build(REASONERS.validate({"name": method}), spec=SPEC)
    module = ReasoningModule(reasoner.network, lr=1e-2)
    module.log_dict = lambda *args, **kwargs: None  # no trainer attached
    batch = next(iter(DataLoader([reasoner.encode(o) for o in observations(demos(4))], batch_size=32)))
    optimiser = module.configure_optimizers()
    losses = []
    for _ in range(60):
        optimiser.zero_grad()
        loss = module.training_step(batch, 0)
        loss.backward()
        optimiser.step()
        losses.append(loss.item())
    assert losses[-1] < 0.5 * losses[0]


def test_two_stage_classifier_reads_the_goal_selected_by_p_o():
    reasoner = REASONERS.build(REASONERS.validate({"name": "ours"}), spec=SPEC)
    batch = next(iter(DataLoader([reasoner.encode(o) for o in observations(demos(1))], batch_size=8)))
    seen = {}
    classifier = reasoner.network.classifier
    classifier.register_forward_hook(lambda m, inputs, out: seen.update(g=inputs[1].clone()))
    reasoner.network(batch, teacher_forcing=True)
    expected = batch.goals[torch.arange(8), batch.o_label]
    torch.testing.assert_close(seen["g"], expected)


def test_random_forest_learns_the_seen_configurations():
    reasoner = REASONERS.build(REASONERS.validate({"name": "rf", "n_estimators": 20}), spec=SPEC, seed=0)
    train = demos(24, seed=0) * 3
    reasoner.fit(observations(train), None)
    assert evaluate(reasoner, demos(24, seed=1))["acc_o"] > 0.8


class _Oracle:
    """Predicts the labels, except for one chosen stage of one chosen trial."""

    def __init__(self, wrong_index=None):
        self.wrong_index = wrong_index

    def labels(self, observations):
        return np.array([[o.o_label, o.g_label] for o in observations])

    def predict(self, observations):
        predictions = self.labels(observations)
        if self.wrong_index is not None:
            predictions[self.wrong_index, 1] += 1
        return predictions


def test_a_trial_succeeds_only_if_all_2n_predictions_are_right():
    episodes = demos(5)
    assert evaluate(_Oracle(), episodes)["sr"] == 1.0
    result = evaluate(_Oracle(wrong_index=9), episodes)  # stage 2 of trial 2 (8 stages per 4of5 trial)
    assert result["sr"] == pytest.approx(0.8)
    assert result["acc_g"] == pytest.approx(1 - 1 / 40)


@pytest.mark.parametrize("method", TORCH_METHODS)
def test_scored_labels_are_the_trained_labels(method):
    reasoner = REASONERS.build(REASONERS.validate({"name": method}), spec=SPEC)
    obs = observations(demos(2))
    encoded = np.array([[int(d.o_label), int(d.g_label)] for d in map(reasoner.encode, obs)])
    np.testing.assert_array_equal(reasoner.labels(obs), encoded)
