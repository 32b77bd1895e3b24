"""GNNExplainer (torch_geometric.explain) on the chain GraphSAGE encoder's P_o output: which node features and
which edges the importance ranking relies on, as in Fig. 4.9."""

from __future__ import annotations

from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from torch import nn  # noqa: E402
from torch_geometric.explain import Explainer, GNNExplainer  # noqa: E402

FEATURES = ("x", "y", "z", "I")


class _EncoderLogits(nn.Module):
    """The explainer calls model(x, edge_index, batch=...): expose the encoder's P_o logits that way."""

    def __init__(self, encoder: nn.Module) -> None:
        super().__init__()
        self.encoder = encoder

    def forward(self, x, edge_index, batch=None):
        return self.encoder.logits(x, edge_index, batch)


@dataclass
class StageExplanation:
    node_mask: np.ndarray  # (nodes, 4)
    edge_mask: np.ndarray  # (edges,)
    edge_index: np.ndarray  # (2, edges)
    products: np.ndarray  # product index of every node
    prediction: int

    @property
    def feature_importance(self) -> dict[str, float]:
        totals = self.node_mask.sum(axis=0)
        totals = totals / totals.sum() if totals.sum() > 0 else totals
        return dict(zip(FEATURES, map(float, totals)))


def explain_stage(reasoner, obs, epochs: int = 200) -> StageExplanation:
    graph = reasoner.encode(obs)
    model = _EncoderLogits(reasoner.network.encoder).eval()
    explainer = Explainer(
        model,
        algorithm=GNNExplainer(epochs=epochs),
        explanation_type="model",
        node_mask_type="attributes",
        edge_mask_type="object",
        model_config=dict(mode="multiclass_classification", task_level="graph", return_type="raw"),
    )
    batch = torch.zeros(graph.num_nodes, dtype=torch.long)
    explanation = explainer(graph.x, graph.edge_index, batch=batch)
    with torch.no_grad():
        prediction = int(model(graph.x, graph.edge_index, batch=batch).argmax(-1))
    return StageExplanation(
        node_mask=explanation.node_mask.detach().numpy(),
        edge_mask=explanation.edge_mask.detach().numpy(),
        edge_index=graph.edge_index.numpy(),
        products=graph.product.numpy(),
        prediction=prediction,
    )


def plot_explanations(explanations: dict[str, StageExplanation], title: str):
    """Feature mask (top row, nodes x features) and edge mask (bottom row, chain with edge weights) per stage."""
    fig, axes = plt.subplots(2, len(explanations), figsize=(4.2 * len(explanations), 5.5), squeeze=False)
    for col, (stage, ex) in enumerate(explanations.items()):
        ax = axes[0, col]
        ax.imshow(ex.node_mask.T, cmap="viridis", aspect="auto")
        ax.set_yticks(range(len(FEATURES)), FEATURES)
        ax.set_xticks(range(len(ex.products)), [f"o{p + 1}" for p in ex.products])
        target = "p (box)" if ex.prediction == 0 else f"o{ex.prediction}"
        ax.set_title(f"{stage}: feature mask (P_o -> {target})")
        ax = axes[1, col]
        xs = np.arange(len(ex.products))
        ax.scatter(xs, np.zeros_like(xs), s=300, c="lightgray", zorder=3)
        for x, p in zip(xs, ex.products):
            ax.text(x, 0, f"o{p + 1}", ha="center", va="center", zorder=4)
        weights = ex.edge_mask / ex.edge_mask.max() if ex.edge_mask.max() > 0 else ex.edge_mask
        for (src, dst), w in zip(ex.edge_index.T, weights):
            ax.annotate(
                "",
                xy=(dst, 0),
                xytext=(src, 0),
                arrowprops=dict(arrowstyle="->", lw=0.5 + 4 * w, color=plt.cm.Reds(0.3 + 0.7 * w)),
            )
        ax.set_title(f"{stage}: edge mask")
        ax.axis("off")
    fig.suptitle(title)
    fig.tight_layout()
    return fig
