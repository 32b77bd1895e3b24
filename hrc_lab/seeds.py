"""The one seed convention of a job: everything random derives from the config's ``seed``, through a named stream.

- numpy draws: a generator per purpose, ``numpy.random.default_rng([seed, stream])``
  (:meth:`hrc_lab.run_context.RunContext.rng`, the stream an int the protocol names);
- a simulator's scenes (robot cells and goal envs reseed from an int): :func:`scene_seed`, the job's seed plus the
  offset of the scenes' purpose below. The offsets lie 1000 or more apart, so for seeds below 1000 no two purposes
  share a scene.
"""

from __future__ import annotations

TEST_SCENES = 1000  # the test trials of Table 3.1, 4.2 and 4.3 (every Table 4.3 system sees the same scenes)
DRL_DEMO_SCENES = 5000  # Table 4.3's DRL: the scripted demonstrations put in its demonstration buffer
DRL_EVAL_SCENES = 9000  # Table 4.3's DRL: its per-epoch evaluation during training
RL_EVAL_SCENES = 10_000  # Fig. 3.12 / 3.13: the per-epoch evaluation of each subtask's agent
EXPERT_DEMO_SCENES = 20_000  # Fig. 3.12 / 3.13: the scripted demonstrations put in each agent's demonstration buffer
DAGGER_SCENES = 30_000  # Table 3.1's DAgger rounds: the training scenes the learned planner rolls in


def scene_seed(seed: int, offset: int) -> int:
    """The int a simulator is seeded with for the scenes of purpose ``offset`` (one of this module's constants)."""
    return offset + seed
