"""DAgger for Table 3.1's two-level planner (hrc_lab.motion.dagger): the aggregation loop, the expert taking over
where the closed loop left the cell, and the protocol switch."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from hrc_lab.env.robot.cell import PICK, PLACE
from hrc_lab.env.robot.expert import ScriptedExpert
from hrc_lab.env.robot.factory import make_env
from hrc_lab.env.robot.settings import ErrorCorrectionConfig
from hrc_lab.experiments.schemas import Table31Protocol
from hrc_lab.motion.dagger import dagger, takeover_demos
from hrc_lab.motion.two_level import run_correction


def test_each_round_aggregates_the_new_demonstrations_and_retrains_on_all():
    trained_on = []

    def train(demos):
        trained_on.append(list(demos))
        return len(demos)

    models, demos = dagger(train, lambda models: [f"from a planner of {models}"], ["a", "b"], rounds=2)
    assert trained_on == [["a", "b"], ["a", "b", "from a planner of 2"],
                          ["a", "b", "from a planner of 2", "from a planner of 3"]]
    assert (models, demos) == (4, trained_on[-1])
    assert dagger(train, None, ["a"], rounds=0) == (1, ["a"])  # off: the original models, no collection


class _ExpertSubgoals:
    """A stand-in for the learned planners: the scripted expert's designed sub-goals (``predict``) and joint steps
    (``act``), every placing sub-goal ``offset`` (m) off in x, as the closed loop's placements are."""

    def __init__(self, env, offset: float) -> None:
        self.expert, self.offset = ScriptedExpert(env), np.array([offset, 0.0, 0.0])

    def predict(self, x, labels, indices, references):
        obj, stage = divmod(int(labels[0]), 2)
        subgoal = self.expert.designed_subgoals(obj + 1, stage)[int(indices[0])]
        return (subgoal + self.offset * (stage == PLACE))[None], np.zeros((1, 3))

    def act(self, r, s):
        return self.expert.joint_step(s)


def test_a_round_demonstrates_the_second_object_from_where_the_loop_left_the_first():
    env = make_env(ErrorCorrectionConfig(task="two_object"), seed=0)  # case 1: blue first, then red
    imprecise = _ExpertSubgoals(env, offset=0.03)
    loop = partial(run_correction, planner=imprecise, ndp=imprecise, classifier=None, n_subgoals=3,
                   stage_labels="ground_truth")
    (demo,) = takeover_demos(env, loop, 1, subgoals_per_stage=5, segmentation_penalty=1e-3, desc="test")
    first, second = env.expert_plan()
    blue_error = np.linalg.norm(demo.obs["object_pos"][:, 3 * first:3 * first + 3] - env.goals[first], axis=1)
    assert blue_error[0] > 0.02  # the loop's placement, not the expert's exact one
    assert np.ptp(blue_error) < 0.005  # and the expert leaves it there
    assert demo.stage_bounds[:, :2].tolist() == [[second, PICK], [second, PLACE]]
    assert set(demo.stage_labels) == {env.stage_label(second, PICK), env.stage_label(second, PLACE)}
    assert demo.stage_subgoals.shape == (2, 5, 3)


@pytest.mark.parametrize("key,value", [("dagger_rounds", -1), ("dagger_episodes", 0)])
def test_the_protocol_rejects_impossible_dagger_settings(key, value):
    with pytest.raises(ValueError, match=f"protocol.{key} must be"):
        Table31Protocol(**{key: value})
