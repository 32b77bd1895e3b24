"""``reasoning=semantic_planner``: the graph semantic planner of Ch.5 (Sec. 5.2.2, Eq. 5.4-5.13).

The assembly graph has one node per part type and one per position, each with two categorical features (type,
position). A detected assembly action "o_i -> p_j" adds a directed edge from position node p_j to object node o_i
(Eq. 5.4), so an object node aggregates the positions it was assembled to. GraphSAGE layers (Eq. 5.5,
mean aggregation, ReLU) give node embeddings Gamma; a mean readout (Eq. 5.6) gives Phi and a linear head the z-way
goal distribution P_g; an MLP on [Phi, P_g] gives the next object P_o (Eq. 5.7); cross-entropy on both (Eq. 5.8).

An LSTM decodes a semantic plan per object from f_lstm = [Gamma_o, P_g] (Eq. 5.9-5.13): at each step the input is
[f_lstm, embedding of the previous word], the previous word being the ground truth in training (teacher forcing) and
the greedy prediction at test, starting from <start> and ending at <end>. The thesis trains the decoder after the
GNN on its node embeddings; here the three losses are summed and trained in one run.
"""

from __future__ import annotations

from dataclasses import dataclass

import lightning.pytorch as pl
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from torch_geometric.data import Data
from torch_geometric.loader import DataLoader
from torch_geometric.nn import global_mean_pool

from hrc_lab.env.assembly.spec import (
    FINISHED,
    AssembleToOrderSpec,
    Scenario,
    assembled_pairs,
    next_object,
    plan_tokens,
)
from hrc_lab.reasoning.chain_sage import SAGEStack
from hrc_lab.reasoning.configs import SemanticPlannerConfig
from hrc_lab.training import FixedStepDataModule, SupervisedModule, steps_per_epoch
from hrc_lab.vocabulary import PAD, START, TokenVocabulary


class Vocabulary(TokenVocabulary):
    """Words of the semantic plans: part types, positions, Finished, and the control tokens."""

    def __init__(self, spec: AssembleToOrderSpec) -> None:
        words = [FINISHED, *spec.types, *(f"p{p}" for p in range(1, spec.n_positions + 1))]
        super().__init__(words, max_len=1 + max(spec.product.values()) + 1)  # part, its positions, <end>


def assembly_graph(spec: AssembleToOrderSpec, pairs: list[tuple[str, int]], vocab: Vocabulary, **labels) -> Data:
    """Nodes: the part types (type id, position 0) then the positions (type 0, position id); edges position ->
    object for every assembled pair (Eq. 5.4). Pairs of unknown types or positions are ignored."""
    n_types = len(spec.types)
    x = [[t + 1, 0] for t in range(n_types)] + [[0, p] for p in range(1, spec.n_positions + 1)]
    edges = [
        (n_types + position - 1, spec.types.index(part))
        for part, position in dict.fromkeys(pairs)
        if part in spec.types and 1 <= position <= spec.n_positions
    ]
    edge_index = torch.tensor(edges, dtype=torch.long).reshape(-1, 2).T
    is_object = torch.arange(len(x)) < n_types
    return Data(x=torch.tensor(x), edge_index=edge_index, is_object=is_object, num_nodes=len(x), **labels)


def scenario_graph(spec: AssembleToOrderSpec, scenario: Scenario, vocab: Vocabulary) -> Data:
    """The graph of a scenario with its ground truth: goal, next object and the plan of every part type."""
    captions = [vocab.encode(plan_tokens(spec, scenario, part)) for part in spec.types]
    return assembly_graph(
        spec,
        assembled_pairs(spec, scenario),
        vocab,
        goal=torch.tensor([scenario.goal]),
        next=torch.tensor([spec.types.index(next_object(spec, scenario))]),
        captions=torch.tensor(captions),
    )


class SemanticPlannerNet(nn.Module):
    def __init__(self, spec: AssembleToOrderSpec, vocab: Vocabulary, cfg: SemanticPlannerConfig) -> None:
        super().__init__()
        self.vocab = vocab
        self.type_embedding = nn.Embedding(len(spec.types) + 1, cfg.feature_dim)
        self.position_embedding = nn.Embedding(spec.n_positions + 1, cfg.feature_dim)
        self.sage = SAGEStack(2 * cfg.feature_dim, cfg.hidden, cfg.layers)
        self.goal_head = nn.Linear(cfg.hidden, spec.n_goals)
        self.next_head = nn.Sequential(
            nn.Linear(cfg.hidden + spec.n_goals, cfg.hidden), nn.ReLU(), nn.Linear(cfg.hidden, len(spec.types))
        )
        self.word_embedding = nn.Embedding(len(vocab), cfg.word_dim)  # Eq. 5.9
        self.lstm = nn.LSTM(cfg.hidden + spec.n_goals + cfg.word_dim, cfg.lstm_hidden, batch_first=True)
        self.word_head = nn.Linear(cfg.lstm_hidden, len(vocab))  # Eq. 5.12

    def encode(self, batch) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Object-node embeddings Gamma_o (B*types, hidden), goal logits, next-object logits, P_g per object."""
        features = torch.cat([self.type_embedding(batch.x[:, 0]), self.position_embedding(batch.x[:, 1])], dim=-1)
        gamma = self.sage(features, batch.edge_index)
        phi = global_mean_pool(gamma, batch.batch)  # Eq. 5.6
        logits_goal = self.goal_head(phi)
        p_goal = logits_goal.softmax(-1)
        logits_next = self.next_head(torch.cat([phi, p_goal], dim=-1))  # Eq. 5.7
        objects = batch.is_object
        return gamma[objects], logits_goal, logits_next, p_goal[batch.batch[objects]]

    def caption_logits(self, f_lstm: torch.Tensor, captions: torch.Tensor) -> torch.Tensor:
        """Teacher forcing (Eq. 5.10-5.12): logits of every word given the previous ground-truth words."""
        previous = torch.cat([torch.full_like(captions[:, :1], self.vocab.index[START]), captions[:, :-1]], dim=1)
        inputs = torch.cat([f_lstm.unsqueeze(1).expand(-1, captions.shape[1], -1), self.word_embedding(previous)], -1)
        hidden, _ = self.lstm(inputs)
        return self.word_head(hidden)

    @torch.no_grad()
    def greedy_decode(self, f_lstm: torch.Tensor) -> torch.Tensor:
        """Eq. 5.13: feed back the most probable word until the maximum plan length."""
        word = torch.full((len(f_lstm),), self.vocab.index[START], dtype=torch.long)
        state, out = None, []
        for _ in range(self.vocab.max_len):
            step = torch.cat([f_lstm, self.word_embedding(word)], dim=-1).unsqueeze(1)
            hidden, state = self.lstm(step, state)
            word = self.word_head(hidden[:, 0]).argmax(-1)
            out.append(word)
        return torch.stack(out, dim=1)


def planner_objective(network: SemanticPlannerNet, batch) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Eq. 5.8 (goal and next-object cross-entropy) plus the decoder's word cross-entropy."""
    gamma_o, logits_goal, logits_next, p_goal = network.encode(batch)
    words = network.caption_logits(torch.cat([gamma_o, p_goal], dim=-1), batch.captions)
    loss_goal = F.cross_entropy(logits_goal, batch.goal)
    loss_next = F.cross_entropy(logits_next, batch.next)
    pad = network.vocab.index[PAD]
    loss_text = F.cross_entropy(words.flatten(0, 1), batch.captions.flatten(), ignore_index=pad)
    loss = loss_goal + loss_next + loss_text
    return loss, {"loss_goal": loss_goal, "loss_next": loss_next, "loss_text": loss_text}


class SemanticPlannerModule(SupervisedModule):
    """:func:`planner_objective` with Adam; logs ``train_loss`` and ``train_loss_{goal,next,text}`` per epoch."""

    def __init__(self, network: SemanticPlannerNet, lr: float) -> None:
        super().__init__(network, planner_objective, lr)


@dataclass
class Plan:
    """The planner's reading of one assembly graph."""

    goal: int
    next_object: str
    guidance: dict[str, list[str]]  # Semantic Guidance: the plan tokens of every part type

    @property
    def control(self) -> list[str]:
        """Semantic Control: [o_next, p, ...] for the robot."""
        return self.guidance[self.next_object]


class SemanticPlanner:
    """Trains the network on scenarios and reads plans off assembly graphs."""

    def __init__(self, spec: AssembleToOrderSpec, cfg: SemanticPlannerConfig, seed: int = 0) -> None:
        self.spec, self.cfg, self.seed = spec, cfg, seed
        self.vocab = Vocabulary(spec)
        self.network = SemanticPlannerNet(spec, self.vocab, cfg)

    def fit(self, scenarios: list[Scenario], trainer: pl.Trainer) -> None:
        samples = [scenario_graph(self.spec, s, self.vocab) for s in scenarios]
        data = FixedStepDataModule(samples, self.cfg.batch_size, steps_per_epoch(self.cfg.steps, trainer))
        trainer.fit(SemanticPlannerModule(self.network, self.cfg.lr), datamodule=data)

    @torch.no_grad()
    def plan(self, assemblies: list[list[tuple[str, int]]], batch_size: int = 512) -> list[Plan]:
        """One plan per list of assembled (part, position) pairs."""
        self.network.eval()
        graphs = [assembly_graph(self.spec, pairs, self.vocab) for pairs in assemblies]
        plans = []
        for batch in DataLoader(graphs, batch_size=batch_size):
            gamma_o, logits_goal, logits_next, p_goal = self.network.encode(batch)
            words = self.network.greedy_decode(torch.cat([gamma_o, p_goal], dim=-1))
            n_types = len(self.spec.types)
            for b in range(len(logits_goal)):
                texts = [self.vocab.decode(words[b * n_types + t]) for t in range(n_types)]
                plans.append(
                    Plan(
                        goal=int(logits_goal[b].argmax()),
                        next_object=self.spec.types[int(logits_next[b].argmax())],
                        guidance=dict(zip(self.spec.types, texts)),
                    )
                )
        return plans


def score_plans(spec: AssembleToOrderSpec, scenarios: list[Scenario], plans: list[Plan]) -> dict[str, float]:
    """A trial succeeds when the goal, the next object and every part type's plan are right (5.4.2)."""
    goal = np.array([p.goal == s.goal for s, p in zip(scenarios, plans)])
    nxt = np.array([p.next_object == next_object(spec, s) for s, p in zip(scenarios, plans)])
    text = np.array(
        [all(p.guidance[t] == plan_tokens(spec, s, t) for t in spec.types) for s, p in zip(scenarios, plans)]
    )
    return {
        "sr": float((goal & nxt & text).mean()),
        "goal_acc": float(goal.mean()),
        "next_acc": float(nxt.mean()),
        "text_acc": float(text.mean()),
    }
