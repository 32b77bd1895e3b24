import numpy as np
import pytest

from hrc_lab.env.assembly.spec import (
    FETCH,
    SCREW,
    TRANSPORT,
    AssembleToOrderSpec,
    HumanWorker,
    Scenario,
    action_labels,
    ambiguous_scenarios,
    indistinguishable,
    next_object,
    parse_assembly,
    plan_tokens,
    scenarios,
)

SPEC = AssembleToOrderSpec()


@pytest.mark.parametrize("n_goals", [1, 2, 3])
def test_62_scenarios_per_goal(n_goals):
    found = scenarios(AssembleToOrderSpec(n_goals=n_goals))
    assert len(found) == 62 * n_goals == len(set(found))
    assert all(0 < len(s.assembled) < 6 for s in found)


def test_action_labels_follow_table_5_1():
    labels = action_labels(SPEC)
    assert len(labels) == 18
    assert labels[:6] == [f"o1->p{p}" for p in range(1, 7)]
    assert labels[12:15] == ["o3->p1", "o3->p4", "o3->p5"]
    assert labels[15:] == [FETCH, TRANSPORT, SCREW]
    assert parse_assembly("o2->p4") == ("o2", 4) and parse_assembly(SCREW) is None


def test_default_goals_cover_every_pair_of_table_5_1():
    used = {(part, p) for goal in SPEC.goals for p, part in enumerate(goal, start=1)}
    assert used == {parse_assembly(label) for label in action_labels(SPEC)[:15]}


def test_expert_task_structure_and_plans():
    scenario = Scenario(goal=0, assembled=frozenset({1, 3}))  # g0 = o3 o1 o1 o1 o2 o2; o3@p1 and o1@p3 done
    assert next_object(SPEC, scenario) == "o1"  # p2 is the first unassembled position
    assert plan_tokens(SPEC, scenario, "o1") == ["o1", "p2", "p4"]
    assert plan_tokens(SPEC, scenario, "o3") == ["o3", "Finished"]
    assert plan_tokens(SPEC, scenario, "o2") == ["o2", "p5", "p6"]


def test_shared_pairs_make_exactly_the_expected_scenarios_ambiguous():
    ambiguous = {(s.goal, tuple(sorted(s.assembled))) for s in ambiguous_scenarios(SPEC)}
    assert ambiguous == {(0, (2,)), (1, (2,)), (0, (3,)), (2, (3,)), (1, (6,)), (2, (6,))}
    assert ambiguous_scenarios(AssembleToOrderSpec(n_goals=1)) == []


def test_indistinguishable_scenarios_are_the_goals_with_the_same_assembled_parts():
    # g0 = o3 o1 o1 o1 o2 o2, g1 = o2 o1 o2 o3 o1 o1, g2 = o1 o2 o1 o2 o3 o1: o1 on p3 is g0's and g2's
    assert indistinguishable(SPEC, Scenario(0, frozenset({3}))) == [Scenario(0, frozenset({3})),
                                                                    Scenario(2, frozenset({3}))]
    assert indistinguishable(SPEC, Scenario(0, frozenset({1, 3}))) == [Scenario(0, frozenset({1, 3}))]
    assert len(indistinguishable(SPEC, Scenario(1, frozenset()))) == 3  # before the first placement: every goal
    assert indistinguishable(AssembleToOrderSpec(n_goals=1), Scenario(0, frozenset())) == [Scenario(0, frozenset())]


@pytest.mark.parametrize(
    "override, message",
    [
        ({"n_goals": 4}, "env.n_goals"),
        ({"goals": [["o1", "o1", "o1", "o1", "o2", "o3"]], "n_goals": 1}, r"env.goals\[0\] uses"),
        ({"goals": [["o1", "o3", "o1", "o1", "o2", "o2"]], "n_goals": 1}, "o3 cannot go to p2"),
    ],
)
def test_bad_products_are_rejected(override, message):
    with pytest.raises(ValueError, match=message):
        AssembleToOrderSpec(**override)


def test_human_worker_assembles_the_goal_and_sometimes_screws():
    human = HumanWorker(SPEC, goal=1, rng=np.random.default_rng(0), p_screw=0.5)
    assembled: set[int] = set()
    seen_screw = False
    while len(assembled) < 6:
        actions = human.next_actions(assembled)
        if actions == [SCREW]:
            seen_screw = True
            assembled.add(min(set(range(1, 7)) - assembled))  # the robot places the next part
            continue
        assert actions[:2] == [FETCH, TRANSPORT]
        part, position = parse_assembly(actions[2])
        assert SPEC.goal(1)[position - 1] == part and position not in assembled
        assembled.add(position)
    assert seen_screw
