"""Config schemas of the reasoning methods (light: no torch import), and their registry.

Every method is registered once, next to its schema, with its implementation, its family (the protocols it is a
row of: :data:`CH4`, Ch.4's package-to-order reasoners of Tables 4.1 and 4.3, Fig. 4.7 and 4.4.5; :data:`CH5`,
Ch.5's assembly planner) and its display name in reports; a variant of a method names the method it varies
(``variant_of``). The protocols' accepted names (:data:`hrc_lab.experiments.schemas.ACCEPTS`) and the reports' rows
and labels (:mod:`hrc_lab.report.ch4_reasoning`) are read from here, so a new method is added in this file alone
(and its ``conf/reasoning/<name>.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass

from hrc_lab.registry import Registry

CH4 = "ch4"  # package-to-order reasoning (Table 4.1, Fig. 4.7, the practical scenarios, Table 4.3)
CH5 = "ch5"  # assembly-to-order planning (Fig. 5.7, Table 5.2)


@dataclass(frozen=True)
class Method:
    """What reports and protocols know of a registered reasoning method besides its schema and implementation."""

    family: str
    label: str  # its row's name in reports
    variant_of: str | None = None  # the method it is an ablation or variant of (a dashed line beside it)


class ReasonerRegistry(Registry):
    """The ``reasoning`` registry: :meth:`Registry.register` plus each method's :class:`Method`."""

    def __init__(self, group: str) -> None:
        super().__init__(group)
        self._methods: dict[str, Method] = {}

    def register(self, name: str, schema: type, target: str | None = None, *, family: str, label: str,
                 variant_of: str | None = None) -> None:
        super().register(name, schema, target)
        self._methods[name] = Method(family, label, variant_of)

    def method(self, name: str) -> Method:
        self.get(name)  # an unknown name is a ConfigError naming the choices
        return self._methods[name]

    def family(self, family: str) -> tuple[str, ...]:
        """The methods of ``family`` in the order they are registered (the order of the reports' rows)."""
        return tuple(name for name, method in self._methods.items() if method.family == family)

    def labels(self, family: str) -> dict[str, str]:
        """Method name -> display name, for the methods of ``family``."""
        return {name: self._methods[name].label for name in self.family(family)}

    def with_variants(self, name: str) -> tuple[str, ...]:
        """``name`` and the methods registered as its variants, in the order they are registered."""
        return (name, *(other for other, method in self._methods.items() if method.variant_of == name))


REASONERS = ReasonerRegistry("reasoning")

# How positions enter the package-to-order encodings (``reasoning.position_frame``; hrc_lab/reasoning/encoding.py):
# (origin, scale). "table_dm": relative to the centre of the table top, in decimetres, so that features are O(1)
# (hrc_lab's default); "table_m": the same in metres; "world_m": the world frame in metres as the simulator reports
# it (the table top 0.8 m up). The thesis does not say how its (x, y, z) node features are scaled or centred.
POSITION_FRAMES = {"table_dm": ("table", 10.0), "table_m": ("table", 1.0), "world_m": ("world", 1.0)}
DEFAULT_POSITION_FRAME = "table_dm"


@dataclass
class TorchReasonerConfig:
    lr: float = 1e-3  # Adam; Ch.4: 1e-3 as in 4.4.1
    batch_size: int = 64
    steps: int = 1000  # gradient steps in all, split over trainer.max_epochs (batches sampled with replacement)

    def __post_init__(self) -> None:
        """Every numeric setting of a torch reasoner (rates, sizes, layer counts) must be > 0."""
        for key, value in vars(self).items():
            if isinstance(value, (int, float)) and not isinstance(value, bool) and value <= 0:
                raise ValueError(f"reasoning.{key} must be > 0, got {value}")


@dataclass
class PackageToOrderReasonerConfig(TorchReasonerConfig):
    """A torch reasoner of Ch.4's package-to-order observations: ``position_frame`` names the frame and unit of
    every position it reads (:data:`POSITION_FRAMES`)."""

    position_frame: str = DEFAULT_POSITION_FRAME

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.position_frame not in POSITION_FRAMES:
            raise ValueError(f"reasoning.position_frame must be one of {sorted(POSITION_FRAMES)}, "
                             f"got {self.position_frame!r}")


@dataclass
class TwoStageConfig(PackageToOrderReasonerConfig):
    """An encoder giving P_o (``layers`` x ``hidden``) and the stage classifier giving P_g (ours, mlp)."""

    hidden: int = 64
    layers: int = 3
    classifier_hidden: int = 64


CHAIN_EDGES = ("chain", "bidirectional", "all_earlier")
READOUTS = ("mean", "node_scores", "pointer")
AGGREGATIONS = ("mean", "max")


@dataclass
class ChainSAGEConfig(TwoStageConfig):
    """``edges``: "chain" links each product's node to the next one (the thesis' reading of E = {e_ij}, default),
    "bidirectional" both ways, "all_earlier" every earlier node to every later one (the other reading of
    "i = 1..m-1 and j = 2..m"). ``readout``: "mean" is Eq. 4.3 + a linear layer (the thesis); "node_scores" is
    hrc_lab's ablation, a score per product node and one for the packaging area from the mean readout; "pointer"
    scores the packaging area by the node scoring it highest (``reasoning=hrc``)."""

    edges: str = "chain"
    readout: str = "mean"

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.edges not in CHAIN_EDGES:
            raise ValueError(f"reasoning.edges must be one of {CHAIN_EDGES}, got {self.edges!r}")
        if self.readout not in READOUTS:
            raise ValueError(f"reasoning.readout must be one of {READOUTS}, got {self.readout!r}")


@dataclass
class HRCConfig(ChainSAGEConfig):
    """hrc_lab's reasoning module (``reasoning=hrc``, :class:`hrc_lab.reasoning.chain_sage.HRCReasoner`): ours'
    network with the all-earlier edges and the pointer readout; ``aggr`` aggregates the neighbours of Eq. 4.1 by
    their "mean" (the thesis) or element-wise "max"; with ``augment`` it trains on the expert's observations plus
    ``augment_copies`` identity-relabelled copies of each (:mod:`hrc_lab.reasoning.augment`)."""

    edges: str = "all_earlier"
    readout: str = "pointer"
    aggr: str = "max"
    augment: bool = True
    augment_copies: int = 4

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.aggr not in AGGREGATIONS:
            raise ValueError(f"reasoning.aggr must be one of {AGGREGATIONS}, got {self.aggr!r}")


FlatMLPConfig = TwoStageConfig


@dataclass
class ObjectGoalGNNConfig(PackageToOrderReasonerConfig):
    hidden: int = 64
    layers: int = 3
    label_scheme: str = "order"  # "order": [74]'s labels (gnn); "task": the thesis' labels (gnn_task)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.label_scheme not in ("order", "task"):
            raise ValueError(f"reasoning.label_scheme must be 'order' or 'task', got {self.label_scheme!r}")


@dataclass
class RandomForestConfig:
    n_estimators: int = 100
    max_depth: int | None = None

    def __post_init__(self) -> None:
        if self.n_estimators < 1:
            raise ValueError(f"reasoning.n_estimators must be >= 1, got {self.n_estimators}")
        if self.max_depth is not None and self.max_depth < 1:
            raise ValueError(f"reasoning.max_depth must be >= 1 or null, got {self.max_depth}")


CHAIN_SAGE = "hrc_lab.reasoning.chain_sage:ChainSAGEReasoner"
OBJECT_GOAL_GNN = "hrc_lab.reasoning.object_goal_gnn:ObjectGoalGNNReasoner"
REASONERS.register("ours", ChainSAGEConfig, CHAIN_SAGE, family=CH4, label="Ours")
# Issue 24's variants of ours, each a row of its own beside the thesis' (conf/reasoning/<name>.yaml sets the keys)
REASONERS.register("ours_all_earlier", ChainSAGEConfig, CHAIN_SAGE, family=CH4, label="Ours, all-earlier edges",
                   variant_of="ours")
REASONERS.register("ours_node_scores", ChainSAGEConfig, CHAIN_SAGE, family=CH4,
                   label="Ours + node scores (hrc_lab)", variant_of="ours")
# hrc_lab's reasoning module (issue 45), a method of its own: its row stands beside the thesis' module, not as a variant
REASONERS.register("hrc", HRCConfig, "hrc_lab.reasoning.chain_sage:HRCReasoner", family=CH4,
                   label="hrc_lab's module")
REASONERS.register("gnn", ObjectGoalGNNConfig, OBJECT_GOAL_GNN, family=CH4, label="GNN [74]")
REASONERS.register("gnn_task", ObjectGoalGNNConfig, OBJECT_GOAL_GNN, family=CH4, label="GNN-task")
REASONERS.register("mlp", FlatMLPConfig, "hrc_lab.reasoning.flat_mlp:FlatMLPReasoner", family=CH4, label="MLP")
REASONERS.register("rf", RandomForestConfig, "hrc_lab.reasoning.random_forest:RandomForestReasoner", family=CH4,
                   label="RF")


@dataclass
class SemanticPlannerConfig(TorchReasonerConfig):
    """Graph semantic planner of Ch.5 (Sec. 5.2.2, Eq. 5.4-5.13): SAGEConv on the assembly graph, goal head,
    next-object MLP, LSTM text decoder."""

    # The thesis gives no learning rate for Ch.5: 3e-3 fits all 186 scenarios in 1,000 steps (1e-3 needs twice as many)
    lr: float = 3e-3
    feature_dim: int = 16  # embedding size of each categorical node feature (type, position)
    hidden: int = 64
    layers: int = 2
    word_dim: int = 16
    lstm_hidden: int = 64


REASONERS.register("semantic_planner", SemanticPlannerConfig, "hrc_lab.reasoning.semantic_planner:SemanticPlanner",
                   family=CH5, label="Graph semantic planner")
