import pytest
import torch
from torch_geometric.loader import DataLoader

from hrc_lab.env.assembly.spec import SCREW, AssembleToOrderSpec, Scenario, scenarios
from hrc_lab.reasoning import REASONERS
from hrc_lab.reasoning.hrc_loop import SemanticPlannerLoop
from hrc_lab.reasoning.semantic_planner import (
    Plan,
    SemanticPlannerModule,
    Vocabulary,
    assembly_graph,
    scenario_graph,
    score_plans,
)

SPEC = AssembleToOrderSpec()


def test_graph_from_an_action_sequence_links_positions_to_objects():
    vocab = Vocabulary(SPEC)
    graph = assembly_graph(SPEC, [("o1", 2), ("o3", 1), ("o1", 2)], vocab)  # a repeated detection adds no edge
    assert graph.num_nodes == 3 + 6
    assert graph.x.tolist()[:4] == [[1, 0], [2, 0], [3, 0], [0, 1]]
    assert sorted(map(tuple, graph.edge_index.T.tolist())) == [(3, 2), (4, 0)]  # p1 -> o3, p2 -> o1
    assert graph.is_object.tolist() == [True] * 3 + [False] * 6


def test_vocabulary_round_trip():
    vocab = Vocabulary(SPEC)
    for tokens in (["o1", "p3", "p4"], ["o2", "Finished"], ["o1", "p1", "p5", "p6"]):
        ids = vocab.encode(tokens)
        assert len(ids) == vocab.max_len
        assert vocab.decode(ids) == tokens


def test_planner_shapes_and_a_falling_loss():
    torch.manual_seed(0)
    planner = REASONERS.build(REASONERS.validate({"name": "semantic_planner"}), spec=SPEC)
    graphs = [scenario_graph(SPEC, s, planner.vocab) for s in scenarios(SPEC)[:40]]
    batch = next(iter(DataLoader(graphs, batch_size=40)))
    gamma_o, logits_goal, logits_next, p_goal = planner.network.encode(batch)
    assert gamma_o.shape == (120, 64) and logits_goal.shape == (40, 3) and logits_next.shape == (40, 3)
    module = SemanticPlannerModule(planner.network, lr=1e-2)
    module.log_dict = lambda *args, **kwargs: None
    optimiser = module.configure_optimizers()
    losses = []
    for _ in range(40):
        optimiser.zero_grad()
        loss = module.training_step(batch, 0)
        loss.backward()
        optimiser.step()
        losses.append(loss.item())
    assert losses[-1] < 0.5 * losses[0]
    plans = planner.plan([[("o1", 2)], []])
    assert len(plans) == 2 and set(plans[0].guidance) == {"o1", "o2", "o3"}


def test_score_needs_goal_next_object_and_every_text():
    scenario = Scenario(0, frozenset({1}))
    right = Plan(0, "o1", {"o1": ["o1", "p2", "p3", "p4"], "o2": ["o2", "p5", "p6"], "o3": ["o3", "Finished"]})
    wrong_text = Plan(0, "o1", {**right.guidance, "o2": ["o2", "p5"]})
    assert score_plans(SPEC, [scenario], [right])["sr"] == 1.0
    assert score_plans(SPEC, [scenario, scenario], [right, wrong_text])["sr"] == pytest.approx(0.5)


class _ScriptedPlanner:
    """Always proposes o1 -> p2, p3 so the loop's mechanics can be checked without training."""

    spec = SPEC

    def __init__(self):
        self.calls = []

    def plan(self, assemblies):
        self.calls.append(list(assemblies[0]))
        guidance = {"o1": ["o1", "p2", "p3"], "o2": ["o2", "p5", "p6"], "o3": ["o3", "Finished"]}
        return [Plan(0, "o1", guidance)]


def test_event_loop_on_a_scripted_sequence():
    placed = []

    def robot(part, position):
        placed.append((part, position))
        return part, position

    printed = []
    planner = _ScriptedPlanner()
    loop = SemanticPlannerLoop(planner, robot, echo=printed.append)
    events = loop.run(["fetch", "transport", "o3->p1", "fetch", "transport", "o1->p4", SCREW])
    assert [e.label for e in events] == ["o3->p1", "o1->p4", SCREW]  # fetch and transport change nothing
    assert planner.calls[1] == [("o3", 1), ("o1", 4)]
    assert placed == [("o1", 2)] and events[-1].command == ("o1", 2)
    assert loop.pairs[-1] == ("o1", 2) and loop.assembled == {1, 2, 4}
    assert "PickandPlace(o1, p2)" in printed[-1] and "guidance: o1, p2, p3" in printed[0]
