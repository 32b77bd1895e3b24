"""Recording a scripted-expert episode of a robot cell as a :class:`~hrc_lab.data.demos.Demo`: what the
``data/collect`` job writes to HDF5 and what the motion module's demonstrations (Table 3.1, 4.2, 4.3) train on."""

from __future__ import annotations

import numpy as np

from hrc_lab.data.demos import OBS_KEYS, Demo


def record_episode(env, expert, action_noise: float = 0.0, rng: np.random.Generator | None = None,
                   reset: bool = True) -> Demo:
    """Run one expert episode from a fresh reset and return it as a :class:`~hrc_lab.data.demos.Demo`; with
    ``reset=False`` the expert starts from the cell's current state (DAgger: it takes over where a closed loop left
    the cell, :mod:`hrc_lab.motion.dagger`).

    ``action_noise`` > 0 (DART, Laskey et al. 2017): the executed action's joint deltas get Gaussian noise of that
    std (rad, drawn from ``rng``) while the expert's own action is recorded, so the demonstrations visit the states
    a slightly-off closed loop reaches, labelled with the expert's correction from there."""
    if action_noise < 0:
        raise ValueError(f"action_noise must be >= 0 rad, got {action_noise}")
    if action_noise and rng is None:
        raise ValueError("action_noise needs an rng (the scene's own generator must not be consumed)")

    env.step_observations = True  # the columns are robosuite's observations, which a lean step computes on request
    obs = env.reset() if reset else env.observations()
    expert.reset()
    episode = {"scenario": getattr(env, "task", None) or "package_to_order", "plan": list(env.expert_plan())}
    if getattr(env, "episode", None) is not None:
        episode |= {
            "configuration": [list(map(int, pair)) for pair in env.episode.configuration],
            "human_order": list(env.episode.human_order),
            "missing": list(env.episode.missing),
        }
    columns: dict[str, list] = {k: [] for k in OBS_KEYS if k in obs}
    actions, states, rewards, dones, labels, indices, subgoals = [], [], [], [], [], [], []
    info = {"success": False}
    while (step := expert.act()) is not None and not env.done:
        for key in columns:
            columns[key].append(np.asarray(obs[key], dtype=np.float32))
        states.append(env.sim.get_state().flatten())
        executed = np.array(step.action, dtype=float)
        if action_noise:
            executed[:-1] += rng.normal(0.0, action_noise, len(executed) - 1)  # joint deltas; suction as commanded
        obs, reward, done, info = env.step(executed)
        actions.append(step.action)
        rewards.append(reward)
        dones.append(done)
        labels.append(step.label)
        indices.append(step.subgoal_index)
        subgoals.append(step.subgoal)
    episode["collisions"] = list(env.collisions)
    return Demo(
        obs={k: np.stack(v) for k, v in columns.items()},
        actions=np.asarray(actions, dtype=np.float32),
        states=np.asarray(states),
        rewards=np.asarray(rewards, dtype=np.float32),
        dones=np.asarray(dones, dtype=bool),
        stage_labels=np.asarray(labels, dtype=np.int64),
        subgoal_indices=np.asarray(indices, dtype=np.int64),
        subgoals=np.asarray(subgoals, dtype=np.float32),
        success=bool(info.get("success", False)),
        model_file=env.sim.model.get_xml(),
        episode=episode,
    )
