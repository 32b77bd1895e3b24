import dataclasses

import numpy as np
import pytest

from hrc_lab.env.robot.spec import PackageToOrderSpec, sample_episode, stage_observations
from hrc_lab.reasoning.encoding import (
    chain_graph,
    flat_vector,
    goal_table,
    object_goal_graph,
    order_labels,
)

SPEC = PackageToOrderSpec(n_objects=5, n_selected=3)
CONFIGURATION = ((1, 2), (3, 0), (4, 1))


def observations(**kwargs):
    return stage_observations(sample_episode(SPEC, CONFIGURATION, np.random.default_rng(0), **kwargs))


def test_chain_graph_has_one_node_per_product_and_next_neighbour_edges():
    obs = observations()[0]
    graph = chain_graph(obs, SPEC)
    assert graph.x.shape == (5, 4)
    assert graph.edge_index.tolist() == [[0, 1, 2, 3], [1, 2, 3, 4]]
    assert graph.x[:, 3].tolist() == [0, 1, 0, 1, 1]  # feature I: selected or not
    expected = (obs.positions[2] - [0, 0, SPEC.table_z]) * 10  # decimetres, the default frame
    np.testing.assert_allclose(graph.x[2, :3].numpy(), expected, rtol=1e-6)
    both = chain_graph(obs, SPEC, "bidirectional")
    assert both.edge_index.shape == (2, 8)


def test_all_earlier_edges_link_every_node_to_every_later_one():
    """The other reading of Sec. 4.2.1's E = {e_ij}, i = 1..m-1, j = 2..m: node i feeds every node j > i."""
    edges = chain_graph(observations()[0], SPEC, "all_earlier").edge_index
    assert sorted(map(tuple, edges.T.tolist())) == [(i, j) for i in range(5) for j in range(i + 1, 5)]
    with pytest.raises(ValueError, match="edges"):
        chain_graph(observations()[0], SPEC, "ring")


def test_chain_graph_drops_missing_products():
    for seed in range(10):
        episode = sample_episode(SPEC, CONFIGURATION, np.random.default_rng(seed), n_missing=2)
        graph = chain_graph(stage_observations(episode)[0], SPEC)
        assert graph.num_nodes == 3
        assert graph.edge_index.shape == (2, 2)
        assert set(graph.product.tolist()).isdisjoint(episode.missing)


def test_goal_table_rows_follow_p_o():
    placing = observations()[1]  # product 2 (index 1) is held, its goal is slot 3
    table = goal_table(placing, SPEC)
    centre = [*placing.slot_positions[:, :2].mean(axis=0), SPEC.table_z]
    slot3 = (placing.slot_positions[2] - centre) * 10  # decimetres, the default frame
    np.testing.assert_allclose(table[0], slot3)  # row 0: the held product's goal
    np.testing.assert_allclose(table[2], slot3)  # row 1+i: product i's goal
    np.testing.assert_array_equal(table[1], 0)  # product 1 is not selected


def test_goal_table_names_the_slot_in_the_box_wherever_the_box_stands():
    """4.4.3: goal positions vary; a position-specified label is a place in the box, so moving the box must not
    change the goal features (in table coordinates a 0.1 m move crosses a slot spacing of 0.08 m)."""
    placing = observations()[1]
    moved = dataclasses.replace(placing, slot_positions=placing.slot_positions + [0.1, -0.05, 0.0])
    np.testing.assert_allclose(goal_table(moved, SPEC), goal_table(placing, SPEC), atol=1e-12)
    assert np.all(np.any(goal_table(placing, SPEC)[[0, 2]] != 0, axis=1))  # no goal encodes as "no goal"


def test_object_goal_graph_is_fully_connected_with_goal_nodes():
    obs = observations()[0]
    graph = object_goal_graph(obs, SPEC, "order")
    n = 5 + 3
    assert graph.x.shape == (n, 3 + 1 + 5 + 2)
    assert graph.edge_index.shape == (2, n * (n - 1))
    assert graph.x[:, 3].sum() == 3  # is_goal
    assert (int(graph.o_label), int(graph.g_label)) == order_labels(obs)


def test_order_labels_do_not_change_between_stages():
    pick, place = observations()[:2]
    assert order_labels(pick) == order_labels(place) == (2, 1)


def test_flat_vector_needs_every_product():
    assert flat_vector(observations()[0], SPEC).shape == (20,)
    with pytest.raises(ValueError, match="every product present"):
        flat_vector(observations(n_missing=1)[0], SPEC)


def test_position_frames_move_and_scale_every_position():
    """``reasoning.position_frame`` (issue 24's ablation): table_dm = table_m x 10; world_m = table_m with the
    table top's height added to z; goals relative to the box in the frame's unit; I untouched."""
    obs = observations()[1]  # a placing stage: a goal in every encoding
    for encode in (lambda f: chain_graph(obs, SPEC, frame=f).x, lambda f: object_goal_graph(obs, SPEC, "task", f).x,
                   lambda f: flat_vector(obs, SPEC, f).reshape(5, 4)):
        table_m, table_dm, world_m = (np.asarray(encode(f)) for f in ("table_m", "table_dm", "world_m"))
        np.testing.assert_allclose(table_dm[:, :3], table_m[:, :3] * 10, rtol=1e-6)
        np.testing.assert_allclose(world_m[:, :3], table_m[:, :3] + [0, 0, SPEC.table_z], rtol=1e-6)
        np.testing.assert_array_equal(table_dm[:, 3:], table_m[:, 3:])
    np.testing.assert_allclose(goal_table(obs, SPEC, "table_dm"), goal_table(obs, SPEC, "table_m") * 10)
    np.testing.assert_allclose(goal_table(obs, SPEC, "world_m"), goal_table(obs, SPEC, "table_m"))


def test_reasoners_encode_in_their_configured_position_frame():
    from hrc_lab.reasoning.configs import REASONERS

    obs = observations()[1]
    for name in ("ours", "mlp", "gnn"):
        reasoner = REASONERS.build(REASONERS.validate({"name": name, "position_frame": "world_m"}), spec=SPEC, seed=0)
        data = reasoner.encode(obs)
        features = data.x_flat.reshape(5, 4) if name == "mlp" else data.x
        assert float(features[:, 2].min()) >= SPEC.table_z  # world z: on or above the table top
        np.testing.assert_allclose(data.goals[0].numpy(), goal_table(obs, SPEC, "world_m"), rtol=1e-6)
    with pytest.raises(ValueError, match="reasoning.position_frame"):
        REASONERS.validate({"name": "mlp", "position_frame": "world_mm"})
