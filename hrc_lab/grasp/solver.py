"""``grasp=gnn_att`` and its baselines: graspability and grasp solutions from the scene graph (Sec. 6.2).

Node features v_i = [f_i, one-hot l_i, g_i] (:mod:`hrc_lab.grasp.graph`) are projected to ``hidden`` units and
passed through ``layers`` WL-GNN layers (Eq. 6.2, PyG ``GraphConv`` with the Eq. 6.1 edge weights and add
aggregation: Gamma_i' = ReLU(W1 Gamma_i + W2 sum_j e_ji Gamma_j)); ``gcn_att`` swaps in ``GCNConv`` (degree-normalised
mean over the node and its neighbours); ★ ``relation`` (:class:`RelationConv`, beyond the thesis) lets each message
see the pair's box geometry, and ★ ``blockers`` adds a head on each edge that learns which neighbour blocks the
part (the labels' blockers) and hands the decoder the blocker types. A linear head gives the graspability P_gra of
each node, trained with binary cross-entropy on the requested nodes (Eq. 6.3).

The solution decoder reads f' = [Gamma_i, one-hot l_i, P_gra] (Eq. 6.7). With attention (LSTM_Att, Eq. 6.4-6.6),
f' is projected into ``segments`` segments f'_s; at each step the score h_t^T W_a f'_s (Eq. 6.4) is softmax-normalised
over the segments (Eq. 6.5) and the weighted sum of the segments is the context (Eq. 6.6), the LSTM's input beside
the embedding of the previous word (the ground truth in training, the greedy choice at test, starting from
<start>). The plain ``lstm`` decoder feeds f' itself at every step. Both start from a state computed from f'.
★ ``transformer`` decodes with Transformer layers instead (:mod:`hrc_lab.grasp.transformer_decoder`).
The thesis trains the decoder on the trained node embeddings; here the two losses are summed and trained in one
run, with P_gra detached in the decoder input.
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
from torch_geometric.nn import GCNConv, GraphConv, MessagePassing
from torch_geometric.utils import scatter

from hrc_lab.env.clutter.rule import longest_solution, solution_words
from hrc_lab.grasp.configs import GraspSolverConfig
from hrc_lab.grasp.graph import PAIR_GEOMETRY_DIM, scene_graph
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.training import FixedStepDataModule, SupervisedModule, binary_accuracy, steps_per_epoch
from hrc_lab.vocabulary import PAD, START, TokenVocabulary


class SolutionVocabulary(TokenVocabulary):
    """The words of grasp solutions over objects of ``classes`` ("grasp", "move b and c", "help") and the control
    tokens; long enough for a solution naming every class but one ("move b and c" for our parts a, b, c)."""

    def __init__(self, classes: tuple[str, ...]) -> None:
        super().__init__(solution_words(classes), longest_solution(classes) + 1)


class AttentionLSTMDecoder(nn.Module):
    """LSTM_Att (Eq. 6.4-6.7), or a plain LSTM fed f' at every step when ``attention`` is False."""

    def __init__(self, feature_dim: int, vocab: SolutionVocabulary, cfg: GraspSolverConfig) -> None:
        super().__init__()
        self.vocab, self.attention, self.segments = vocab, cfg.decoder == "lstm_att", cfg.segments
        self.word_embedding = nn.Embedding(len(vocab), cfg.word_dim)
        self.initial_state = nn.Linear(feature_dim, 2 * cfg.lstm_hidden)
        if self.attention:
            self.segment_dim = max(8, cfg.hidden // cfg.segments)
            self.to_segments = nn.Linear(feature_dim, cfg.segments * self.segment_dim)
            self.w_a = nn.Linear(self.segment_dim, cfg.lstm_hidden, bias=False)  # Eq. 6.4
            step_dim = self.segment_dim
        else:
            step_dim = feature_dim
        self.cell = nn.LSTMCell(step_dim + cfg.word_dim, cfg.lstm_hidden)
        self.word_head = nn.Linear(cfg.lstm_hidden, len(vocab))

    def _start(self, features: torch.Tensor):
        h, c = torch.tanh(self.initial_state(features)).chunk(2, dim=-1)
        segments = (self.to_segments(features).view(len(features), self.segments, self.segment_dim)
                    if self.attention else None)
        return (h, c), segments

    def _step(self, features, segments, state, word):
        h, _ = state
        if self.attention:
            scores = torch.einsum("bh,bsh->bs", h, self.w_a(segments))  # Eq. 6.4
            alpha = scores.softmax(dim=-1)  # Eq. 6.5
            context = torch.einsum("bs,bsd->bd", alpha, segments)  # Eq. 6.6
        else:
            context = features
        state = self.cell(torch.cat([context, self.word_embedding(word)], dim=-1), state)
        return self.word_head(state[0]), state

    def forward(self, features: torch.Tensor, captions: torch.Tensor) -> torch.Tensor:
        """Teacher forcing: logits (B, L, vocab) of every word given the previous ground-truth words."""
        state, segments = self._start(features)
        previous = torch.cat([torch.full_like(captions[:, :1], self.vocab.index[START]), captions[:, :-1]], dim=1)
        logits = []
        for t in range(captions.shape[1]):
            step, state = self._step(features, segments, state, previous[:, t])
            logits.append(step)
        return torch.stack(logits, dim=1)

    @torch.no_grad()
    def greedy(self, features: torch.Tensor) -> torch.Tensor:
        state, segments = self._start(features)
        word = torch.full((len(features),), self.vocab.index[START], dtype=torch.long, device=features.device)
        out = []
        for _ in range(self.vocab.max_len):
            step, state = self._step(features, segments, state, word)
            word = step.argmax(-1)
            out.append(word)
        return torch.stack(out, dim=1)


def solution_decoder(feature_dim: int, vocab: SolutionVocabulary, cfg: GraspSolverConfig) -> nn.Module:
    """The decoder ``grasp.decoder`` names: LSTM_Att or the plain LSTM, or ★ a Transformer
    (:mod:`hrc_lab.grasp.transformer_decoder`)."""
    if cfg.decoder == "transformer":
        from hrc_lab.grasp.transformer_decoder import TransformerSolutionDecoder

        return TransformerSolutionDecoder(feature_dim, vocab, cfg)
    return AttentionLSTMDecoder(feature_dim, vocab, cfg)


class RelationConv(MessagePassing):
    """★ Eq. 6.2 with relational messages (hrc_lab, beyond the thesis):
    Gamma_i' = W1 Gamma_i + sum_j e_ji MLP([Gamma_i, Gamma_j, r_ji]), with e_ji Eq. 6.1's weight and r_ji the pair's
    box geometry (:func:`hrc_lab.grasp.graph.pair_geometry`). In Eq. 6.2 a neighbour's message W2 Gamma_j is the same
    whichever side of i it lies on, so whether j is in the way of i's fingers or on top of i must be read from
    appearance alone; here the message depends on where j is relative to i."""

    def __init__(self, channels: int, edge_dim: int = PAIR_GEOMETRY_DIM) -> None:
        super().__init__(aggr="add")
        self.root = nn.Linear(channels, channels)
        self.relation = nn.Sequential(nn.Linear(2 * channels + edge_dim, channels), nn.ReLU(),
                                      nn.Linear(channels, channels))

    def forward(self, x: torch.Tensor, edge_index: torch.Tensor, edge_weight: torch.Tensor,
                edge_attr: torch.Tensor) -> torch.Tensor:
        return self.root(x) + self.propagate(edge_index, x=x, edge_weight=edge_weight, edge_attr=edge_attr)

    def message(self, x_i: torch.Tensor, x_j: torch.Tensor, edge_weight: torch.Tensor,
                edge_attr: torch.Tensor) -> torch.Tensor:
        return edge_weight.unsqueeze(-1) * self.relation(torch.cat([x_i, x_j, edge_attr], dim=-1))


CONV_LAYERS = {
    "graph": lambda hidden: GraphConv(hidden, hidden, aggr="add"),  # WL-GNN, Eq. 6.2
    "gcn": lambda hidden: GCNConv(hidden, hidden),
    "relation": RelationConv,
}


class GraspSolverNet(nn.Module):
    def __init__(self, node_dim: int, n_classes: int, vocab: SolutionVocabulary, cfg: GraspSolverConfig) -> None:
        super().__init__()
        self.n_classes = n_classes
        self.input = nn.Sequential(nn.LayerNorm(node_dim), nn.Linear(node_dim, cfg.hidden), nn.ReLU())
        self.relational = cfg.conv == "relation"
        self.convs = nn.ModuleList(CONV_LAYERS[cfg.conv](cfg.hidden) for _ in range(cfg.layers))
        self.grasp_head = nn.Linear(cfg.hidden, 1)
        pair_dim = 2 * cfg.hidden + PAIR_GEOMETRY_DIM
        self.blocker_head = (
            nn.Sequential(nn.Linear(pair_dim, cfg.hidden), nn.ReLU(), nn.Linear(cfg.hidden, 1))
            if cfg.blockers else None
        )
        evidence = n_classes if cfg.blockers else 0
        self.decoder = solution_decoder(cfg.hidden + n_classes + 1 + evidence, vocab, cfg)

    def encode(self, batch) -> tuple[torch.Tensor, torch.Tensor]:
        """Node embeddings Gamma (Eq. 6.2) and graspability logits (Eq. 6.3)."""
        gamma = self.input(batch.x)
        geometry = (batch.edge_attr,) if self.relational else ()
        for conv in self.convs:
            gamma = F.relu(conv(gamma, batch.edge_index, batch.edge_weight, *geometry))
        return gamma, self.grasp_head(gamma).squeeze(-1)

    def blocker_logits(self, gamma: torch.Tensor, batch) -> torch.Tensor:
        """★ Per edge j -> i, the logit that j keeps i from being grasped, from [Gamma_i, Gamma_j, r_ji]."""
        source, target = batch.edge_index
        return self.blocker_head(torch.cat([gamma[target], gamma[source], batch.edge_attr], dim=-1)).squeeze(-1)

    def decoder_input(self, gamma: torch.Tensor, batch, p_grasp: torch.Tensor,
                      blocker_logits: torch.Tensor | None = None) -> torch.Tensor:
        """f' = [Gamma_i, l_i, P_gra] (Eq. 6.7); ★ with the blocker head, followed by the blocker types' evidence:
        per type, the highest probability that a neighbour of that type blocks i."""
        parts = [gamma, F.one_hot(batch.label, self.n_classes).float(), p_grasp.unsqueeze(-1)]
        if self.blocker_head is not None:
            source, target = batch.edge_index
            typed = torch.sigmoid(blocker_logits).unsqueeze(-1) * F.one_hot(batch.label[source], self.n_classes)
            parts.append(scatter(typed.float(), target, dim=0, dim_size=len(gamma), reduce="max"))
        return torch.cat(parts, dim=-1)


def labelled_nodes(batch) -> int:
    """The batch size the losses of the Ch.6 models are averaged over: their labelled nodes."""
    return int(batch.labelled.sum())


def solver_objective(network: GraspSolverNet, batch) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Binary cross-entropy on graspability (Eq. 6.3) plus the decoder's word cross-entropy, on labelled nodes (★
    with the blocker head, plus its binary cross-entropy on the edges into labelled nodes); the graspability
    accuracy."""
    gamma, logits = network.encode(batch)
    mask = batch.labelled
    loss_grasp = F.binary_cross_entropy_with_logits(logits[mask], batch.graspable[mask])
    blockers, terms = None, {}
    if network.blocker_head is not None:
        blockers = network.blocker_logits(gamma, batch)
        into_labelled = mask[batch.edge_index[1]]
        terms["loss_blockers"] = F.binary_cross_entropy_with_logits(  # summed: a batch may have no such edge
            blockers[into_labelled], batch.blocks[into_labelled], reduction="sum") / max(int(into_labelled.sum()), 1)
        blockers = blockers.detach()
    f_prime = network.decoder_input(gamma, batch, torch.sigmoid(logits).detach(), blockers)[mask]
    words = network.decoder(f_prime, batch.solution[mask])
    pad = network.decoder.vocab.index[PAD]
    loss_text = F.cross_entropy(words.flatten(0, 1), batch.solution[mask].flatten(), ignore_index=pad)
    accuracy = binary_accuracy(logits[mask] > 0, batch.graspable[mask] > 0.5)
    loss = loss_grasp + loss_text + sum(terms.values())
    return loss, {"loss_grasp": loss_grasp, "loss_text": loss_text, **terms, "grasp_acc": accuracy}


class GraspSolverModule(SupervisedModule):
    """:func:`solver_objective` with Adam and ``grasp.schedule``; logs ``train_loss``, ``train_loss_grasp``,
    ``train_loss_text`` and ``train_grasp_acc`` per epoch, averaged over labelled nodes."""

    def __init__(self, network: GraspSolverNet, cfg: GraspSolverConfig) -> None:
        super().__init__(network, solver_objective, cfg.lr, batch_size=labelled_nodes, schedule=cfg.schedule,
                         warmup_steps=cfg.warmup_steps)


@dataclass
class NodeReading:
    """The solver's reading of one node: graspability probability and decoded solution."""

    p_grasp: float
    solution: list[str]

    @property
    def graspable(self) -> bool:
        return self.p_grasp > 0.5


class GraspSolver:
    """Trains the network on labelled scene graphs and reads graspability and solutions off new ones; ``classes``:
    the object labels l_i (the detector's classes)."""

    needs_union_features = False

    def __init__(self, spec, cfg: GraspSolverConfig, classes: tuple[str, ...], seed: int = 0) -> None:
        self.spec, self.cfg, self.classes, self.seed = spec, cfg, tuple(classes), seed
        self.vocab = SolutionVocabulary(self.classes)
        self.network: GraspSolverNet | None = None

    def graph(self, nodes: SceneNodes, requested: np.ndarray, **targets) -> Data:
        """The scene graph of Eq. 6.1 with the request flags g_i."""
        return scene_graph(
            nodes.features,
            nodes.labels,
            nodes.boxes,
            nodes.image_size,
            requested,
            self.classes,
            self.cfg.edges,
            self.cfg.distance_filter,
            **targets,
        )

    def training_graph(self, nodes: SceneNodes, request: set[str]) -> Data:
        """The request flags the detected objects of the requested types; those matched to a part carry its
        graspability and solution (the others, and false detections, no loss). Each edge j -> i carries whether j's
        part is among the blockers of i's (``blocks``, read by ★ ``grasp.blockers``)."""
        requested = nodes.requested(request)
        parts = np.maximum(nodes.truth, 0)
        graph = self.graph(
            nodes,
            requested,
            graspable=torch.as_tensor(nodes.rule_graspable[parts], dtype=torch.float32),
            solution=torch.tensor([self.vocab.encode(nodes.rule_solution[p]) for p in parts],
                                  dtype=torch.long).reshape(len(parts), self.vocab.max_len),  # also 0 detections
            labelled=torch.as_tensor(requested & (nodes.truth >= 0)),
        )
        graph.blocks = torch.tensor([  # per edge j -> i: j's part is among i's part's blockers (★ grasp.blockers)
            bool(nodes.truth[i] >= 0 and nodes.truth[j] >= 0 and nodes.truth[j] in nodes.rule_blockers[nodes.truth[i]])
            for j, i in graph.edge_index.t().tolist()], dtype=torch.float32)
        return graph

    def fit(self, graphs: list[Data], trainer: pl.Trainer) -> None:
        """``graphs`` (from :meth:`training_graph`) carry ``graspable``, ``solution`` and ``labelled`` per node."""
        if not graphs:
            raise ValueError("no training graphs")
        torch.manual_seed(self.seed)
        self.network = GraspSolverNet(graphs[0].x.shape[1], len(self.classes), self.vocab, self.cfg)
        data = FixedStepDataModule(graphs, self.cfg.batch_size, steps_per_epoch(self.cfg.steps, trainer))
        trainer.fit(GraspSolverModule(self.network, self.cfg), datamodule=data)

    @torch.no_grad()
    def read(self, graphs: list[Data], batch_size: int = 256) -> list[list[NodeReading]]:
        """Per graph, per node: P_gra and the decoded solution."""
        if self.network is None:
            raise RuntimeError("GraspSolver.read before fit")
        self.network.eval()
        readings = []
        for batch in DataLoader(graphs, batch_size=batch_size):
            gamma, logits = self.network.encode(batch)
            p = torch.sigmoid(logits)
            blockers = self.network.blocker_logits(gamma, batch) if self.network.blocker_head is not None else None
            words = self.network.decoder.greedy(self.network.decoder_input(gamma, batch, p, blockers))
            for b in range(batch.num_graphs):
                nodes = (batch.batch == b).nonzero().flatten()
                readings.append([NodeReading(float(p[i]), self.vocab.decode(words[i])) for i in nodes])
        return readings
