"""Public benchmarks of the DRL agent: DDPG + HER (``rl=ddpg_her``, :mod:`hrc_lab.rl`) on gymnasium-robotics' Fetch
tasks (:mod:`hrc_lab.rl.benchmarks`), the tasks the HER reference implementation was published on, trained by the
same agent and epoch loop as the thesis' robot cells (``conf/experiment/rl/fetch.yaml``).

**Epoch**: the HER reference implementation's (:mod:`hrc_lab.rl.trainer`): ``rl.cycles_per_epoch`` cycles of
``rl.episodes_per_cycle`` training episodes (50 steps each), each cycle followed by ``rl.gradient_steps`` gradient
steps and one target update; then ``protocol.eval_episodes`` episodes of the deterministic policy on held-out goals.
Every epoch logs ``success_rate`` (``info["is_success"]`` at the evaluation episodes' last step), ``final_distance``
(|achieved - desired goal| then, m), the epoch's training rates (``train_success_rate``, ``train_final_distance``,
``train_moved_rate``: episodes that moved the object more than 2 cm; the robot cells' grip, collision and guidance
rates are 0 here), ``env_steps_per_s``, ``updates_per_s`` and ``epoch_s`` as MLflow metrics with ``step`` = the
epoch; the final agent (networks and normaliser, no replay buffer) is an artifact, saved every
``protocol.checkpoint_every`` epochs too: a killed run resumed (``resume_from=<run id>``) trains on from that
agent, with an empty replay buffer, and holds the whole curve.
"""

from __future__ import annotations

from hrc_lab.run_context import RunContext

AGENT_DIR = "agents/fetch"


def rl_fetch(ctx: RunContext) -> dict[str, float]:
    """Train DDPG + HER on ``protocol.env_id`` for ``protocol.epochs`` epochs (module docstring); the success rate
    after the last epoch and the best after any epoch."""
    from hrc_lab.rl.agent import save_agent
    from hrc_lab.rl.benchmarks import train_fetch
    from hrc_lab.rl.trainer import episodes_per_epoch

    protocol, rl = ctx.cfg.protocol, ctx.cfg.rl

    def save(agent) -> None:
        save_agent(agent, ctx.output_dir / AGENT_DIR, replay_buffer=False)
        ctx.tracker.log_artifact(ctx.output_dir / AGENT_DIR, AGENT_DIR)

    train_fetch(protocol.env_id, rl, protocol.epochs, seed=ctx.seed, eval_episodes=protocol.eval_episodes,
                log=lambda metrics, epoch: ctx.tracker.log_metrics(metrics, step=epoch), save=save,
                checkpoint_every=protocol.checkpoint_every, resume=lambda envs: ctx.resume_agent(AGENT_DIR, envs),
                on_resume=ctx.tracker.copy_history)  # the curve up to the checkpoint, from the runs it continues
    history = ctx.tracker.client.get_metric_history(ctx.tracker.run_id, "success_rate")
    curve = [m.value for m in sorted(history, key=lambda m: m.step)]  # resumed epochs included
    return {
        "final_success_rate": float(curve[-1]),
        "best_success_rate": float(max(curve)),
        "n_episodes": float(protocol.epochs * episodes_per_epoch(rl)),
    }
