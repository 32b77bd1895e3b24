"""Config schemas of the motion module's sub-goal planners and the RRT-Connect baseline (light: no torch or OMPL
import), and their registry."""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc_lab.registry import Registry

MOTIONS = Registry("motion")

# Where a Ch.3 stage's chain of training pairs begins (hrc_lab.motion.two_level.correction_pairs)
STAGE_STARTS = ("demonstrated", "executed")
# What names the object a Ch.3 picking stage goes for (hrc_lab.motion.two_level.picking_label)
STAGE_LABELS = ("classifier", "picking_classifier", "ground_truth")
# Whose path a Ch.3 stage's re-sampled sub-goals come from (hrc_lab.data.segmentation.stage_subgoals): "eef", the lip
# as measured (robosuite's robot0_eef_pos), or "lip_target", the lip at the commanded joints, where the demonstrator
# was going. The servo lags about one control step, so while the expert descends the measured lip is 2-3.5 cm above
# the commanded one, and a stage that ends in motion (the last placement: the expert releases once its command
# reaches the place pose) ends that far above where the expert placed.
# Each: (its demo observation key, the control steps it leads the measured lip by).
SUBGOAL_PATHS = {"eef": ("robot0_eef_pos", 0), "lip_target": ("lip_target_pos", 1)}
# What the Ch.3 sub-goal planner observes besides r (hrc_lab.motion.two_level.correction_input)
PLANNER_INPUTS = ("full", "selected")
# What the neural dynamic planner's training sub-goal s is (hrc_lab.motion.two_level.dynamics_pairs)
NDP_TARGETS = ("designed", "path")
PATH_ACTIONS = ("step", "mean")
# The GPR baseline's RBF length scales (hrc_lab.motion.configs.SubgoalConfig.gpr_kernel)
GPR_KERNELS = ("ard", "isotropic")


@dataclass
class NDPConfig:
    """Neural dynamic planner (Fig. 3.3, Eq. 3.5): three ReLU layers from Delta = s - r to joint actions."""

    hidden: int = 128  # not given in the thesis; 64 units take > 30 steps for the long first reach from home
    mode: str = "regression"  # "regression": joint deltas (MSE); "direction": -1/0/1 per joint (3.3)
    lr: float = 1e-3
    steps: int = 6000  # gradient steps
    batch_size: int = 128
    # What s is in a training pair (r_t, s, a_t) (hrc_lab.motion.two_level.dynamics_pairs): "designed", the
    # waypoint the expert was heading for; "path", the demonstrated end-effector position path_steps later in the
    # same stage (hindsight sub-goals: Ch.3's sub-goal planner proposes points of the demonstrated path, which a
    # fixed-start task's waypoints never resemble; in the place cell the designed-target direction planner
    # answered "stay" to the first planned sub-goal and no guided episode held the part, issue 43)
    targets: str = "designed"
    path_steps: list[int] = field(default_factory=lambda: [2, 4, 8])
    # targets=path only: the action a_t of the pair (r_t, s = end effector h steps later): "step", the expert's step
    # at t; "mean", its mean step over the h steps, the motion that takes r_t to s. With "step" the direction
    # planner stopped ~7 cm above its last picking sub-goal and stayed (every joint "stay"; Fig. 3.12's place cell,
    # the expert slows near the part), so the guide alone held the part in 5-55 % of episodes (docs/chapters/ch3_rl.md)
    path_action: str = "step"

    def __post_init__(self) -> None:
        if self.mode not in ("regression", "direction"):
            raise ValueError(f"motion.ndp.mode must be 'regression' or 'direction', got '{self.mode}'")
        if self.targets not in NDP_TARGETS:
            raise ValueError(f"motion.ndp.targets must be one of {list(NDP_TARGETS)}, got '{self.targets}'")
        if self.path_action not in PATH_ACTIONS:
            raise ValueError(f"motion.ndp.path_action must be one of {list(PATH_ACTIONS)}, got '{self.path_action}'")
        if self.path_action != "step" and self.targets != "path":
            raise ValueError(f"motion.ndp.path_action={self.path_action} needs motion.ndp.targets=path (a designed "
                             f"waypoint's pair has the expert's one step), got targets={self.targets}")
        if not self.path_steps or min(self.path_steps) < 1:
            raise ValueError(f"motion.ndp.path_steps must be a non-empty list of steps >= 1, got {self.path_steps}")
        for key in ("hidden", "lr", "steps", "batch_size"):
            if getattr(self, key) <= 0:
                raise ValueError(f"motion.ndp.{key} must be > 0, got {getattr(self, key)}")


@dataclass
class ClassifierConfig:
    """Task classifier c(x) of the Ch.3 two-level planner (3.2.1): an MLP from the raw observation to the stage label,
    trained with cross-entropy (hrc_lab.motion.subgoal.StageClassifier). Sizes are not given in the thesis."""

    hidden: int = 64
    lr: float = 1e-3
    steps: int = 2000  # gradient steps
    batch_size: int = 128

    def __post_init__(self) -> None:
        for key in ("hidden", "lr", "steps", "batch_size"):
            if getattr(self, key) <= 0:
                raise ValueError(f"motion.classifier.{key} must be > 0, got {getattr(self, key)}")


@dataclass
class SubgoalConfig:
    """A sub-goal regressor: ``kind`` vi (Fig. 3.2, Eq. 3.1-3.4), mlp (deterministic) or gpr (scikit-learn RBF);
    ``use_labels`` False is the thesis' VI baseline without task labels."""

    kind: str = "vi"
    use_labels: bool = True
    hidden: int = 64
    lr: float = 1e-3  # thesis 4.4.2.1
    steps: int = 3000
    batch_size: int = 64
    kl_weight: float = 1e-3  # weight of D_kl[q(z) || N(0, 1)] (Eq. 3.3) on standardised sub-goals; not in the thesis
    likelihood_std: float = 0.1  # std of p(s | z) in standardised units (Eq. 3.4)
    gpr_max_points: int = 1500  # GPR is O(n^3): fit on a random subset of this size
    # The GPR's RBF kernel (4.4.2.1: "a Radial Basis Function (RBF) kernel"): ``isotropic``, one fitted length scale
    # for all inputs (scikit-learn's ``RBF()``); ``ard``, one per input, so an input the sub-goal does not depend on
    # gets a long one. Isotropic reproduces the thesis' Table 4.2 GPR row (R^2 ~0.97, SR 0.1-0.4 on unseen
    # product-slot pairs); ARD extrapolates over r and scores 0.6-0.96 (issue 24, reports/ch4_motion.md).
    gpr_kernel: str = "isotropic"
    # Training-set jitter of r (the last 3 inputs): ``r_jitter_copies`` noisy copies of every pair with N(0,
    # ``r_jitter_m``^2) on r. In closed loop a sub-goal is planned from wherever the dynamic planner stopped (within
    # the reach tolerance), not from the expert's exact pose; without it the planner is off by ~1 cm there.
    r_jitter_m: float = 0.01
    r_jitter_copies: int = 4
    # One label per (stage, sub-goal index) instead of per stage: the planner is told which of a stage's sub-goals
    # it proposes rather than inferring its progress through the stage from r. Not in the thesis; without it our
    # closed-loop picking sub-goals drift ~1-2 cm above the part (errors in r compound along a stage).
    label_per_subgoal: bool = False
    # Every position before r enters relative to r (x_i - r), r itself absolute, as the issue-20 ablation of the
    # planner's input asks ("the requested part's position relative to r"); the jitter of r moves them with it.
    # Not in the thesis.
    relative_to_r: bool = False
    # The planner predicts s minus its stage's reference position (the part a picking stage picks; when placing,
    # the goals' reference: green in Ch.3, hrc_lab.motion.two_level.correction_reference, and the box p in Ch.4,
    # package_pairs) instead of s in the world frame: a picking stage's last sub-goal is then the same point on the
    # part wherever the part lies. Not in the thesis; the world-frame regression from 20 demonstrations put Table
    # 3.1's second picks 2-22 cm from the part's centre (issue 46).
    relative_targets: bool = False
    # What the Ch.3 sub-goal planner observes besides r (hrc_lab.motion.two_level.correction_input): "full", the
    # thesis' three object positions (3.3); "selected", the labelled object's and green's. Ch.4's input is its own
    # (o_selected or p, Fig. 4.4).
    planner_input: str = "full"
    # Ch.3 placing sub-goals are moved by the lip's horizontal offset from the held part's centre (measured when each
    # sub-goal is planned), so that the part, not the lip, reaches the planned place
    # (hrc_lab.motion.two_level.grasp_shift); not in the thesis. The demonstrations grip parts at their centre, so the
    # planner learned lip sub-goals for a centred grip. Off, so that the runs before it keep their meaning; its
    # measured effect, with and without a longer-trained planner: docs/chapters/ch3_rl.md ("Placing through the grip")
    place_through_grasp: bool = False
    ndp: NDPConfig = field(default_factory=NDPConfig)
    classifier: ClassifierConfig = field(default_factory=ClassifierConfig)  # Ch.3's c(x); Ch.4 labels its stages

    def __post_init__(self) -> None:
        if self.kind not in ("vi", "mlp", "gpr"):
            raise ValueError(f"motion.kind must be 'vi', 'mlp' or 'gpr', got '{self.kind}'")
        if self.planner_input not in PLANNER_INPUTS:
            raise ValueError(f"motion.planner_input must be one of {list(PLANNER_INPUTS)}, got '{self.planner_input}'")
        if self.gpr_kernel not in GPR_KERNELS:
            raise ValueError(f"motion.gpr_kernel must be one of {list(GPR_KERNELS)}, got '{self.gpr_kernel}'")
        for key in ("hidden", "lr", "steps", "batch_size", "likelihood_std", "gpr_max_points"):
            if getattr(self, key) <= 0:
                raise ValueError(f"motion.{key} must be > 0, got {getattr(self, key)}")
        if self.r_jitter_m < 0 or self.r_jitter_copies < 0:
            raise ValueError(f"motion.r_jitter_m and motion.r_jitter_copies must be >= 0, got {self.r_jitter_m}, "
                             f"{self.r_jitter_copies}")
        if self.kl_weight < 0:
            raise ValueError(f"motion.kl_weight must be >= 0, got {self.kl_weight}")


@dataclass
class RRTConnectConfig:
    """RM+RRT-Connect baseline of Table 4.3 (4.4.3, [138], [139]): OMPL's RRT-Connect in the joint space [base,
    shoulder, elbow] between inverse-kinematics solutions of the expert's waypoints."""

    timeout_s: float = 5.0  # OMPL solve time per plan; no exact solution by then is a failed trial ("timeout")
    range_rad: float = 0.0  # RRT-Connect's extension length; 0: OMPL's default (0.2 of the space's extent)
    simplify: bool = True  # OMPL's shortcutting and smoothing of the found path
    # Motion checking step as a fraction of the space's extent (18.8 rad for the joint limits): 0.0005 is ~0.5 deg
    # per check, at most ~8 mm of lip motion. OMPL's default 0.01 steps ~10 deg.
    collision_resolution: float = 0.0005
    # Distance the arm, cup and held product keep from obstacles on planned paths (the servo lags and the weld of a
    # held product gives); the straight descents and lifts at the parts are checked for contact only
    clearance_m: float = 0.01
    ik_iterations: int = 200  # damped least-squares iterations per inverse-kinematics query
    ik_tolerance_m: float = 0.001  # lip position error of a converged inverse-kinematics solution
    ik_damping: float = 0.05  # lambda of the damped least squares (the scripted expert's)
    hover_m: float = 0.08  # lip above a product's top face before the descent (the expert's HOVER)

    def __post_init__(self) -> None:
        for key in ("timeout_s", "ik_iterations", "ik_tolerance_m", "ik_damping", "hover_m"):
            if getattr(self, key) <= 0:
                raise ValueError(f"motion.{key} must be > 0, got {getattr(self, key)}")
        for key in ("range_rad", "clearance_m"):
            if getattr(self, key) < 0:
                raise ValueError(f"motion.{key} must be >= 0, got {getattr(self, key)}")
        if not 0 < self.collision_resolution < 1:
            raise ValueError(f"motion.collision_resolution must be in (0, 1), got {self.collision_resolution}")


MOTIONS.register("tc_vi", SubgoalConfig, "hrc_lab.motion.subgoal:build_subgoal_planner")
MOTIONS.register("tc_vi_indexed", SubgoalConfig, "hrc_lab.motion.subgoal:build_subgoal_planner")
MOTIONS.register("tc_vi_object", SubgoalConfig, "hrc_lab.motion.subgoal:build_subgoal_planner")
MOTIONS.register("vi", SubgoalConfig, "hrc_lab.motion.subgoal:build_subgoal_planner")
MOTIONS.register("mlp", SubgoalConfig, "hrc_lab.motion.subgoal:build_subgoal_planner")
MOTIONS.register("gpr", SubgoalConfig, "hrc_lab.motion.subgoal:build_subgoal_planner")
MOTIONS.register("rrt_connect", RRTConnectConfig, "hrc_lab.motion.rrt_connect:build_rrt_connect")
