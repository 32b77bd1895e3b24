"""gymnasium-robotics' Fetch tasks as an ``env`` of the config (``conf/env/fetch.yaml``): a public benchmark for the
DRL agents, not a world of the thesis. Nothing here builds them (``hrc_lab.rl.benchmarks.make_fetch_env`` does,
inside the ``rl_fetch`` protocol); this module imports no simulator, so validating a config stays fast."""

from __future__ import annotations

from dataclasses import dataclass

# the tasks of Plappert et al. 2018 (arXiv:1802.09464) that hrc_lab trains, in gymnasium-robotics 1.4's versions
FETCH_ENV_IDS = ("FetchReach-v4", "FetchPush-v4", "FetchPickAndPlace-v4")


@dataclass(frozen=True)
class FetchSpec:
    """One Fetch task (50-step episodes, sparse reward: -1 until the goal is within 5 cm). An experiment sets
    ``env_id`` from its protocol's (``conf/experiment/rl/fetch.yaml``), so runs are named and tagged by the task
    (``scenario``), as the robot cells' runs are by theirs."""

    env_id: str = "FetchReach-v4"

    def __post_init__(self) -> None:
        if self.env_id not in FETCH_ENV_IDS:
            raise ValueError(f"env.env_id: unknown Fetch env id '{self.env_id}' (rl/fetch sets it from "
                             f"protocol.env_id); choose one of {list(FETCH_ENV_IDS)}")

    @property
    def cell(self) -> str:
        return "fetch"

    @property
    def scenario(self) -> str:
        return self.env_id
