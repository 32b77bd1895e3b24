"""The held-out scenes a Ch.3 agent is evaluated on after every epoch and, as the final policy, after the last
(Fig. 3.12 / 3.13, :mod:`~hrc_lab.rl.trainer`;
Table 4.3's DRL draws its epochs' scenes by :func:`evaluation_seed` too):
their own seed stream, apart from the training and demonstration scenes, so that a saved agent's evaluation can be
replayed scene for scene (``scripts/rl_final_policies.py``, which fetches the run with
:func:`hrc_lab.tracking.saved_run`)."""

from __future__ import annotations

from typing import Any

from hrc_lab.seeds import RL_EVAL_SCENES, scene_seed


def evaluation_env(env_cfg: Any, rl_cfg: Any, seed: int, subtask: int):
    """The held-out scenes a run's agent of ``subtask`` is evaluated on (its own seed stream, apart from training)."""
    from hrc_lab.rl.goal_env import make_goal_env

    return make_goal_env(env_cfg, rl_cfg, seed=scene_seed(seed, RL_EVAL_SCENES), subtask=subtask)


EPOCH_SEED_STRIDE = 1000  # epoch e's evaluation scenes are seeded 1000 e + k
FINAL_EVALUATION_SEED = 10**7  # the final policy's scenes (episode k: this + k), after every epoch's up to 10^4


def evaluation_seed(epoch: int) -> int:
    """The first scene seed of epoch ``epoch``'s evaluation (episode k: this + k)."""
    return EPOCH_SEED_STRIDE * epoch
