import math

import numpy as np
import pytest

from hrc_lab.env.robot.spec import (
    PICK,
    PLACE,
    PackageToOrderSpec,
    count_goal_configurations,
    goal_configurations,
    sample_episode,
    stage_observations,
)


@pytest.mark.parametrize("n, m, expected", [(2, 3, 6), (3, 3, 6), (3, 5, 60), (4, 5, 120)])
def test_goal_configurations_are_mCn_times_n_factorial(n, m, expected):
    spec = PackageToOrderSpec(n_objects=m, n_selected=n)
    configurations = goal_configurations(spec)
    assert len(configurations) == expected == math.comb(m, n) * math.factorial(n)
    assert len(set(configurations)) == expected
    assert count_goal_configurations(spec) == expected


def test_more_slots_than_products_counts_partial_permutations():
    spec = PackageToOrderSpec(n_objects=5, n_selected=2, n_slots=4)
    assert len(goal_configurations(spec)) == math.comb(5, 2) * 4 * 3


def test_spec_rejects_impossible_orders():
    with pytest.raises(ValueError, match="n_selected"):
        PackageToOrderSpec(n_objects=3, n_selected=4)
    with pytest.raises(ValueError, match="n_slots"):
        PackageToOrderSpec(n_objects=5, n_selected=3, n_slots=2)


def test_pending_shuffle_puts_each_product_in_a_random_cell():
    """Without it product i stays in cell i; with it the products take a permutation of the cells, so one product's
    picking position spans the pending area."""
    configuration = ((1, 2), (3, 0), (4, 1))
    fixed, shuffled = PackageToOrderSpec(n_objects=5, n_selected=3), PackageToOrderSpec(n_objects=5, n_selected=3,
                                                                                        pending_shuffle=True)
    cells = fixed.nominal_pending()[:, 0]

    def cell_of_each_product(spec, seed):
        x = sample_episode(spec, configuration, np.random.default_rng(seed)).positions[:, 0]
        return np.abs(x[:, None] - cells[None, :]).argmin(axis=1)

    assert all((cell_of_each_product(fixed, seed) == np.arange(5)).all() for seed in range(10))
    drawn = np.array([cell_of_each_product(shuffled, seed) for seed in range(40)])
    assert all(sorted(row) == list(range(5)) for row in drawn)  # a permutation: one product per cell
    assert all(len(set(drawn[:, product])) == 5 for product in range(5))  # every product visits every cell


def test_case1_follows_the_expert_task_structure():
    spec = PackageToOrderSpec(n_objects=5, n_selected=3)
    configuration = ((1, 2), (3, 0), (4, 1))  # products 2, 4, 5 go to slots 3, 1, 2
    observations = stage_observations(sample_episode(spec, configuration, np.random.default_rng(0)))
    assert [o.stage for o in observations] == [PICK, PLACE] * 3
    assert [o.target for o in observations] == [1, 1, 3, 3, 4, 4]
    assert [o.o_label for o in observations] == [2, 0, 4, 0, 5, 0]  # 0 = packaging area p at placing
    assert [o.g_label for o in observations] == [0, 3, 0, 1, 0, 2]  # 0 = picking stage, else slot + 1
    assert [o.order for o in observations] == [0, 0, 1, 1, 2, 2]
    placing = observations[1]
    assert placing.positions[1, 2] == pytest.approx(spec.table_z + spec.lift_height)  # held product is lifted
    assert observations[2].packed[1] and observations[2].positions[1, 1] > 0.2  # then rests in the box


def test_case2_robot_continues_after_the_human():
    spec = PackageToOrderSpec(n_objects=5, n_selected=4)
    configuration = goal_configurations(spec)[7]
    for seed in range(20):
        episode = sample_episode(spec, configuration, np.random.default_rng(seed), case=2)
        selected = [p for p, _ in configuration]
        assert 1 <= len(episode.human_order) < len(selected)
        observations = stage_observations(episode)
        robot = [o.target for o in observations[::2]]
        assert robot == sorted(set(selected) - set(episode.human_order))
        assert all(observations[0].packed[p] for p in episode.human_order)


def test_missing_products_are_restocked_after_the_rest():
    spec = PackageToOrderSpec(n_objects=5, n_selected=3)
    configuration = ((0, 0), (2, 1), (4, 2))
    rng = np.random.default_rng(3)
    episode = sample_episode(spec, configuration, rng, n_missing=2)
    observations = stage_observations(episode)
    first = observations[0]
    assert not first.present[list(episode.missing)].any()
    assert np.isnan(first.positions[list(episode.missing)]).all()
    order = [o.target for o in observations[::2]]
    missing_selected = [p for p in order if p in episode.missing]
    assert order[len(order) - len(missing_selected) :] == missing_selected
    assert observations[-1].present.all()


def test_sampling_is_deterministic_under_a_seed():
    spec = PackageToOrderSpec(n_objects=5, n_selected=4)
    configuration = goal_configurations(spec)[0]
    a = sample_episode(spec, configuration, np.random.default_rng(5), case=2)
    b = sample_episode(spec, configuration, np.random.default_rng(5), case=2)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.human_order == b.human_order


def test_positions_stay_in_their_cells_and_do_not_overlap():
    spec = PackageToOrderSpec(n_objects=5, n_selected=4)
    episode = sample_episode(spec, goal_configurations(spec)[0], np.random.default_rng(0))
    gaps = np.diff(episode.positions[:, 0])
    assert (gaps > spec.product_size).all()
