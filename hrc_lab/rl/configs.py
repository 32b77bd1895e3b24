"""Config schema of the reinforcement-learning agents (light: no torch or stable-baselines3 import), and their
registry.

``ddpg_her`` is the DRL baseline of 3.3 and of Table 4.3 (DDPG with a HER replay buffer, sparse reward);
``ddpg_her_guided`` is Algorithm 1 (3.2.3): the same agent whose exploration the two-level planner corrects in a
fraction ``lam`` of the episodes. The thesis gives the algorithms, the guidance ratio lambda (0.7, 1 and 0 in
Fig. 3.13), delta_g = 0.05 m, delta_r = 0.01 m and 40 steps per subtask (3.4.3), and the training lengths (550
epochs in Fig. 3.13, 5000 iterations in Table 4.3); the DDPG and HER hyper-parameters below it does not give, and
they are those of the HER paper (Andrychowicz et al. 2017, ref. [19]) unless a comment says otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc_lab.motion.configs import STAGE_LABELS
from hrc_lab.registry import Registry

RLS = Registry("rl")

GUIDANCES = ("none", "ndp", "ndp_direction")
SUCTIONS = ("action", "auto")
STARTS = ("scene", "held", "sequence")
GOAL_STRATEGIES = ("future", "final", "episode")  # stable-baselines3's GoalSelectionStrategy values
TARGET_UPDATES = ("cycle", "step")
GUIDED_EPISODES = ("replay", "demos")
REWARDS = ("sparse", "dense")


@dataclass
class RLConfig:
    """DDPG + HER and Algorithm 1's guidance (:mod:`hrc_lab.rl.agent`, :mod:`hrc_lab.rl.guidance`)."""

    # --- episodes (3.3, 3.4.3); how many the agent trains is the protocol's (e.g. protocol.epochs) ---
    steps_per_subtask: int = 40  # control steps per pick-and-place subtask (3.4.3: "the max step is 40")
    delta_r: float | None = None  # delta_r of Eq. 3.6 / 4.7 while training; null: env.sim.success_threshold
    # action: the policy's last action dimension switches the cup (on when > 0; a product is released where the
    # agent chooses, which packing several products needs); auto: the action is the joints only, 3.3's
    # [q'_base, q'_shoulder, q'_elbow, q'_wrist3], and the cup grips the part whose top face it touches and holds
    # it to the episode's end (hrc_lab.rl.goal_env)
    suction: str = "action"
    # scene: episodes start from the sampled scene (the thesis), a later subtask's earlier objects set onto their
    # goals and the arm at home; sequence: as scene, but the scripted expert has done the earlier subtasks, so the
    # arm and those objects are where it left them (as subtasks trained in sequence follow one another, and as
    # every demonstration the guide learned from goes on; from home, c(x_1) named the placed part again, issue 43);
    # held: the scripted expert has already picked the goal object and lifted it, so an episode is the placing half
    # alone (issue 19's diagnostic, not in the thesis)
    start: str = "scene"
    # --- the task as 3.3 states it (hrc_lab.rl.goal_env's docstring); each default is the faithful reading ---
    # the parts' rotational symmetry order about z: the achieved yaw, and every yaw error of the reward, is taken
    # modulo 2 pi / order, so a 5 x 5 cm cuboid turned by 90 degrees scores as yaw 0 (4; capped at 2 for a part with
    # a rectangular footprint). 1: the raw yaw (a quarter turn is 1.57 rad off). 1, 2 or 4
    yaw_symmetry: int = 4
    # relative: the action's wrist-3 dimension turns the tool relative to its yaw, i.e. 0 keeps the tool's (and a
    # held part's) yaw while the base turns (wrist 3 gets action + HRCCell.wrist3_holding_yaw(dq_base)); absolute:
    # the raw wrist-3 joint delta (a held part turns with the base unless the agent matches it). Needs
    # env.sim.yaw_action
    wrist3: str = "relative"
    # rl.suction=auto only. support: the cup releases the held part once it was lifted (1 cm) and then touches one of
    # its allowed supports (the table, or the part it stacks on), so the support, not the cup, sets its final height;
    # off until the lip has left it, then on again (it can be picked again). never: the cup holds it to the end
    release: str = "support"
    # hrc_lab's, not in Eq. 3.6: after a collision every reward of the episode is -1, in the agent's own transitions
    # and in HER's relabelled ones (the reward reads the transition's info; Eq. 3.7 counts a trial with a collision
    # as failed, but Eq. 3.6's reward does not see it, so nothing taught the agent to avoid one). false: Eq. 3.6
    collision_fails: bool = False
    # sparse: Eq. 3.6 / 4.7 (0 within delta_r of every goal, else -1). dense: -sum over the goal objects of
    # |P_obj - P_goal| (the norm Eq. 3.6 thresholds), the setting of Fig. 3.12's text ("guiding the learning of the
    # DRL even with dense rewards", 3.4.3). Success is Eq. 3.6's either way (info["is_success"])
    reward: str = "sparse"
    # --- DDPG (HER paper: Adam 1e-3, 3 x 256 ReLU layers, batch 256, gamma 0.98, polyak 0.95, 20 % Gaussian noise) ---
    learning_rate: float = 1e-3
    # Adam's step size (actor and critic) falls linearly from learning_rate at the first epoch to this at the run's
    # last epoch (hrc_lab.rl.trainer.learning_rate_at); null: constant (the HER reference). Not in the thesis: a
    # trained Fig. 3.13 agent (one object, lambda 0.7, 60 epochs at 1e-3) continued 6 epochs at 1e-4 placed within
    # delta_r in 0.68-0.95 (mean 0.82) of 40 held-out scenes per epoch, at 1e-3 in 0.63-0.83 (mean 0.72)
    # (scripts/rl_continue.py; docs/chapters/ch3_rl.md)
    final_learning_rate: float | None = None
    net_arch: list[int] = field(default_factory=lambda: [256, 256, 256])  # actor and critic hidden layers
    batch_size: int = 256
    gamma: float = 0.98
    tau: float = 0.05  # soft target update, 1 - polyak
    action_noise_std: float = 0.2  # std of the Gaussian exploration noise on the [-1, 1] actions
    buffer_size: int = 1_000_000
    # HER paper: observations and goals normalised by running mean / std, clipped to +-5 (hrc_lab.rl.normalization).
    # Without it DDPG + HER did not learn even a reach in the UR5e's joint space (scripts/rl_reach_check.py: SR 0.00
    # at every evaluation to 400 episodes; with it 0.70 after 50 and 0.60-1.00 after; docs/chapters/ch3_rl.md)
    normalize_inputs: bool = True
    # HER paper's DDPG (hrc_lab.rl.ddpg.HerDDPG): the actor's penalty on its [-1, 1] actions, the share of
    # exploration steps that take a uniformly random action, and critic targets clipped to [-1 / (1 - gamma), 0].
    # Without them (0, 0, false: SB3's DDPG) the policy saturated at the action bounds and drove the cup into the
    # table; with them the placing half (rl.start=held, delta_r 0.05, lambda 0.7) reached evaluation SR 0.1-0.5
    # after 120 episodes, from 0.00 (docs/chapters/ch3_rl.md)
    action_l2: float = 1.0
    random_eps: float = 0.3
    clip_return: bool = True
    learning_starts: int = 1000  # random-action warm-up steps (not in the thesis; SB3 default is 100)
    # --- the training loop (hrc_lab.rl.trainer), structured as the HER reference implementation (OpenAI baselines'
    # her: an epoch is ``cycles_per_epoch`` cycles; a cycle collects ``episodes_per_cycle`` episodes, then runs
    # ``gradient_steps`` gradient steps, then one soft target update; the normaliser's statistics follow the stored
    # episodes). Reference values: 50 cycles, 2 episodes per worker, 40 gradient steps, polyak 0.95 per cycle ---
    cycles_per_epoch: int = 50
    episodes_per_cycle: int = 2  # over all ``n_envs`` environments: a multiple of n_envs
    gradient_steps: int = 40  # per cycle
    # cycle: one soft update of the target networks per cycle (the reference); step: after every gradient step
    # (stable-baselines3's DDPG, whose targets then move ``gradient_steps`` times faster)
    target_update: str = "cycle"
    # environments stepped in parallel (stable-baselines3's SubprocVecEnv when > 1, one process each), so a job
    # uses every core it is given
    n_envs: int = 1
    # --- demonstrations (Nair et al. 2018, the reference's ``bc_loss`` / ``q_filter``): a second buffer of
    # demonstration episodes, HER-relabelled like the agent's own; every batch holds ``demo_batch_size`` of them, and
    # the actor also minimises ``bc_weight`` x the squared error to their actions (summed over the demonstration
    # samples, the reference's aux/prm loss weights 0.0078 / 0.001), only where the critic rates the demonstrated
    # action above the policy's (``q_filter``). No demonstration buffer without demonstrations ---
    demo_batch_size: int = 32  # of rl.batch_size 256: Nair et al.'s share (128 of 1024)
    bc_weight: float = 7.8
    # Nair et al.'s Q-filter (BC only where Q(s, a_demo) > Q(s, pi(s))). Off: in the one-object correction cell
    # (50 demonstrations, 2 x 256, BC start, 2000 critic-only steps, seed 0) the filtered actor lost the pick within
    # two epochs (evaluation grip 0.95 -> 0.45 -> 0.00, SR 0.25 -> 0.00) while the unfiltered one kept it (grip
    # 1.00 / 0.95) and rose to SR 0.30 by epoch 3 (issue 43's note)
    q_filter: bool = False
    # Before its first update with demonstrations, the actor clones them for ``bc_pretrain_steps`` batches (a
    # pure behaviour-cloning start) and the critic alone then learns that policy's values for
    # ``critic_warmup_steps`` gradient steps before the actor follows it. Without them the Q-filter of an untrained
    # critic passed 5-8 % of the demonstration samples and the actor lost the demonstrated behaviour within 50
    # episodes (issue 43); Nair et al. start from scratch. 0 / 0: their method as written
    bc_pretrain_steps: int = 5000
    critic_warmup_steps: int = 2000
    # Algorithm 1 "stores expert transition" for guided episodes: ``replay`` stores them in the one replay buffer
    # like the agent's own (the thesis' reading: one buffer R); ``demos`` also puts each guided episode into the
    # demonstration buffer, so the guide's corrected actions are cloned under the Q-filter
    guided_episodes: str = "replay"
    # Algorithm 1's guided branch: "Select action a_t according to current policy" (the pure-RL branch: "Pure RL
    # exploration"). true: the agent's action in a guided episode carries the exploration noise too (action_noise_std,
    # random_eps); false: it is the current policy's action, corrected where it strays beyond delta_g, so only the
    # unguided episodes (a share 1 - lam) explore. Measured (one object, lam 0.7, delta_g 0.05, no scripted
    # demonstrations, seed 0): final policy SR 0.01 against 0.00 with the noise; within delta_g the policy's own
    # action, not its noise, is what spoils the placement (docs/chapters/ch3_rl.md)
    guided_exploration: bool = True
    # --- HER (ref. [19]: k = 4 goals per transition, "future" strategy) ---
    n_sampled_goal: int = 4
    goal_selection_strategy: str = "future"
    # --- Algorithm 1 (3.2.3) ---
    guidance: str = "none"  # none | ndp (d regresses joint deltas) | ndp_direction (d gives -1/0/1 per joint, 3.3)
    lam: float = 0.7  # guidance ratio lambda: the probability that an episode is guided (Fig. 3.13: 0.7, 1, 0)
    delta_g: float = 0.05  # guidance threshold delta_g, m: correct when |p'_T - p_{t+1}| > delta_g
    # H_lo: control steps on one sub-goal before the next is planned (the thesis does not give it; Ch.3's
    # two-level execution allows 30), and the distance at which the sub-goal counts as reached before that
    subgoal_steps: int = 30
    subgoal_tolerance: float = 0.008
    # What names the object a guided episode's planner goes for (the rules of Table 3.1's protocol.stage_labels,
    # hrc_lab.motion.two_level.picking_label): ``classifier`` Algorithm 1's l = c(x_1), read as the object of its
    # label; ``picking_classifier`` c(x_1)'s most likely picking label; ``ground_truth`` the object whose goal the
    # episode trains (a diagnosis of c(x), not the thesis). With rl.start=scene a later subtask starts with the
    # earlier objects on their goals and the arm at home, a state no demonstration shows, and c(x_1) named the
    # placed part again; rl.start=sequence starts it as the demonstrations go on
    stage_labels: str = "classifier"

    def __post_init__(self) -> None:
        for key in ("steps_per_subtask", "batch_size", "buffer_size", "n_sampled_goal", "subgoal_steps",
                    "cycles_per_epoch", "episodes_per_cycle", "gradient_steps", "n_envs"):
            if getattr(self, key) < 1:
                raise ValueError(f"rl.{key} must be >= 1, got {getattr(self, key)}")
        if self.final_learning_rate is not None and not 0 < self.final_learning_rate <= self.learning_rate:
            raise ValueError(f"rl.final_learning_rate must be in (0, rl.learning_rate={self.learning_rate}] or null "
                             f"(constant), got {self.final_learning_rate}")
        for key in ("learning_rate", "action_noise_std", "delta_g", "subgoal_tolerance"):
            if not getattr(self, key) > 0:
                raise ValueError(f"rl.{key} must be > 0, got {getattr(self, key)}")
        if self.delta_r is not None and not 0 < self.delta_r < 0.5:
            raise ValueError(f"rl.delta_r must be in (0, 0.5) m or null (env.sim.success_threshold), "
                             f"got {self.delta_r}")
        if not self.net_arch or min(self.net_arch) < 1:
            raise ValueError(f"rl.net_arch must be a non-empty list of layer widths >= 1, got {self.net_arch}")
        if not 0 < self.gamma <= 1:
            raise ValueError(f"rl.gamma must be in (0, 1], got {self.gamma}")
        if not 0 < self.tau <= 1:
            raise ValueError(f"rl.tau must be in (0, 1], got {self.tau}")
        if self.action_l2 < 0:
            raise ValueError(f"rl.action_l2 must be >= 0, got {self.action_l2}")
        if not 0 <= self.random_eps <= 1:
            raise ValueError(f"rl.random_eps must be in [0, 1], got {self.random_eps}")
        if self.learning_starts < 0:
            raise ValueError(f"rl.learning_starts must be >= 0, got {self.learning_starts}")
        if self.episodes_per_cycle % self.n_envs:
            raise ValueError(f"rl.episodes_per_cycle must be a multiple of rl.n_envs={self.n_envs} (each environment "
                             f"runs the same number of episodes per cycle), got {self.episodes_per_cycle}")
        if self.target_update not in TARGET_UPDATES:
            raise ValueError(f"rl.target_update must be one of {list(TARGET_UPDATES)}, got '{self.target_update}'")
        if not 0 <= self.demo_batch_size < self.batch_size:
            raise ValueError(f"rl.demo_batch_size must be in [0, rl.batch_size={self.batch_size}), "
                             f"got {self.demo_batch_size}")
        if self.bc_pretrain_steps < 0 or self.critic_warmup_steps < 0:
            raise ValueError(f"rl.bc_pretrain_steps and rl.critic_warmup_steps must be >= 0, got "
                             f"{self.bc_pretrain_steps} and {self.critic_warmup_steps}")
        if self.bc_weight < 0:
            raise ValueError(f"rl.bc_weight must be >= 0, got {self.bc_weight}")
        if self.guided_episodes not in GUIDED_EPISODES:
            raise ValueError(f"rl.guided_episodes must be one of {list(GUIDED_EPISODES)}, got '{self.guided_episodes}'")
        if self.goal_selection_strategy not in GOAL_STRATEGIES:
            raise ValueError(f"rl.goal_selection_strategy must be one of {list(GOAL_STRATEGIES)}, "
                             f"got '{self.goal_selection_strategy}'")
        if self.suction not in SUCTIONS:
            raise ValueError(f"rl.suction must be one of {list(SUCTIONS)}, got '{self.suction}'")
        if self.start not in STARTS:
            raise ValueError(f"rl.start must be one of {list(STARTS)}, got '{self.start}'")
        if self.yaw_symmetry not in (1, 2, 4):
            raise ValueError(f"rl.yaw_symmetry must be 1, 2 or 4 (the part's rotational symmetry order about z), "
                             f"got {self.yaw_symmetry}")
        if self.wrist3 not in ("relative", "absolute"):
            raise ValueError(f"rl.wrist3 must be one of ['relative', 'absolute'], got '{self.wrist3}'")
        if self.release not in ("support", "never"):
            raise ValueError(f"rl.release must be one of ['support', 'never'], got '{self.release}'")
        if self.reward not in REWARDS:
            raise ValueError(f"rl.reward must be one of {list(REWARDS)}, got '{self.reward}'")
        if self.guidance not in GUIDANCES:
            raise ValueError(f"rl.guidance must be one of {list(GUIDANCES)}, got '{self.guidance}'")
        if not 0 <= self.lam <= 1:
            raise ValueError(f"rl.lam must be in [0, 1], got {self.lam}")
        if not self.guided_exploration and self.guidance == "none":
            raise ValueError("rl.guided_exploration=false needs guided episodes (rl.guidance ndp or ndp_direction)")
        if self.stage_labels not in STAGE_LABELS:
            raise ValueError(f"rl.stage_labels must be one of {list(STAGE_LABELS)}, got '{self.stage_labels}'")


RLS.register("ddpg_her", RLConfig, "hrc_lab.rl.agent:build_ddpg_her")
RLS.register("ddpg_her_guided", RLConfig, "hrc_lab.rl.agent:build_guided_ddpg_her")
