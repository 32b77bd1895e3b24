"""The held-out scenes a Ch.3 agent is evaluated on after every epoch (Fig. 3.12 / 3.13, :mod:`~hrc_lab.rl.trainer`;
Table 4.3's DRL draws its epochs' scenes by :func:`evaluation_seed` too):
their own seed stream, apart from the training and demonstration scenes, so that a saved agent's evaluation can be
replayed scene for scene (``scripts/rl_final_policies.py``); :func:`saved_run` fetches what such a replay needs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hrc_lab.seeds import RL_EVAL_SCENES, scene_seed


def evaluation_env(env_cfg: Any, rl_cfg: Any, seed: int, subtask: int):
    """The held-out scenes a run's agent of ``subtask`` is evaluated on (its own seed stream, apart from training)."""
    from hrc_lab.rl.goal_env import make_goal_env

    return make_goal_env(env_cfg, rl_cfg, seed=scene_seed(seed, RL_EVAL_SCENES), subtask=subtask)


def evaluation_seed(epoch: int) -> int:
    """The first scene seed of epoch ``epoch``'s evaluation (episode k: this + k)."""
    return 1000 * epoch


@dataclass
class SavedRun:
    """A finished Ch.3 RL run as its scripts replay it: its validated config, seed and saved agents' folder
    (``agents/subtask<k>/``)."""

    cfg: Any
    seed: int
    agents: Path


def saved_run(client: Any, run_id: str, directory: str) -> SavedRun:
    """Download run ``run_id``'s resolved config and saved agents into ``directory`` (an MLflow ``client``)."""
    from omegaconf import OmegaConf

    from hrc_lab.config import register_schemas, validate_config

    register_schemas()
    cfg = validate_config(OmegaConf.load(client.download_artifacts(run_id, "config/resolved.yaml", directory)))
    agents = Path(client.download_artifacts(run_id, "agents", directory))
    return SavedRun(cfg, int(client.get_run(run_id).data.params["seed"]), agents)
