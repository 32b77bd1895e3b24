"""RM+RRT-Connect, the conventional baseline of Table 4.3 (thesis 4.4.3): the reasoning module's decisions (which
product, which goal slot) executed by RRT-Connect [138] (Kuffner & LaValle 2000: two trees, grown from the start
and from the goal, each extending towards random samples and then greedily connecting to the other) from OMPL
[139], with an inverse kinematic solver giving the joint configurations of the waypoints. The environmental
information is taken at the start of each stage; every product but the one handled is an obstacle.

Our set-up (what the thesis leaves open):

- Configuration space: the cell's action space, the 3-D joint space q = [base, shoulder, elbow] within the UR5e's
  joint limits (OMPL ``RealVectorStateSpace(3)``). Wrist 1 and 2 follow the tool-down rule of
  :meth:`~hrc_lab.env.robot.cell.HRCCell.joint_targets` (wrist1 = -pi/2 - shoulder - elbow, which must stay within
  its limit; wrist2 = -pi/2); wrist 3 keeps its angle.
- Collision checking: q is set in a scratch ``mujoco.MjData`` copy of the live scene
  (:meth:`~hrc_lab.env.robot.cell.HRCCell.scratch_state`: a held product moves rigidly with the cup, at its pose
  relative to the cup when the stage starts), then ``mj_kinematics`` and ``mj_collision``. A contact of the arm, the
  cup or the held product is forbidden by the cell's own rule
  (:meth:`~hrc_lab.env.robot.cell.HRCCell.forbidden_contact`: arm links touch nothing but the arm, its mount and the
  cup; a held product touches nothing but the cup and its supports) and, while nothing is held, by the cup touching a
  product other than the one being picked (the rule's ``pick_target``). The scratch model's arm, cup and product geoms
  (and their bodies, for the broadphase) get a contact margin of ``clearance_m``: planned paths keep that distance
  (the servo lags the command and the weld of a held product gives); the straight descents and lifts at the products
  are checked for contact only. Its collision filter leaves only the pairs that can be forbidden (the moving robot or
  the held product with anything else), so a check costs ~30 us. OMPL checks a motion every ``collision_resolution``
  of the space's extent (0.0005: ~0.5 deg, <= 8 mm of lip motion), so every configuration between two checked ones is
  within ~4 mm of one of them, inside the clearance.
- Inverse kinematics: damped least squares on the MuJoCo Jacobian of the lip w.r.t. q
  (:meth:`~hrc_lab.env.robot.cell.HRCCell.lip_kinematics`, the scripted expert's step without its 5 deg cap),
  started from the current command; with three joints for a 3-D lip position the solution is the branch nearest
  the start. A solution that does not converge or is in collision is an ``ik`` failure.
- Waypoints, as the scripted expert's (:mod:`hrc_lab.env.robot.expert`): picking = RRT-Connect to the lip
  ``hover_m`` above the product's top face, straight down to the top face, grip, straight up to transit height;
  placing = RRT-Connect (the held product part of the robot) to the lip above the goal slot at transit height,
  straight down onto the slot (the caller releases). If the start of a picking stage is too close to an obstacle
  (the product just released), the lip first rises ``hover_m`` straight up.
- Execution: the path is cut into joint steps of at most ``max_joint_step`` (5 deg) per joint, each sent as the
  cell's delta action relative to the commanded joints (the servo lags the command by about a step). At the end
  of a descent the arm holds still until the measured lip reaches the commanded one; a picking stage then grips
  with one still step with suction on (as the two-level execution does).

Planning time of a stage = its inverse kinematics, collision-checker set-up and OMPL solve (with simplification),
wall clock. OMPL's sampler is seeded before every solve from the module's seed, so a trial is reproducible.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass

import mujoco
import numpy as np
import ompl.base as ob
import ompl.geometric as og
import ompl.util as ou

from hrc_lab.env.robot.cell import PICK
from hrc_lab.motion.configs import RRTConnectConfig
from hrc_lab.motion.two_level import Rollout

PICK_LIP_ABOVE = 0.002  # lip above the top face at the end of a picking descent, m (the expert's)
PLACE_LIP_ABOVE = 0.003  # lip above the goal's top face at the end of a placing descent, m (the expert's)
STRAIGHT_STEP_M = 0.01  # lip spacing of the IK waypoints of a straight descent or lift
IK_MAX_STEP = 0.2  # largest joint change of one damped least-squares iteration, rad (stay on the start's branch)
SETTLE_STEPS = 5  # still steps at most for the measured lip to reach the commanded one
SETTLE_TOLERANCE = 0.003  # m
# a trial's failure for each of :meth:`RRTConnectMotion.plan`'s (its goal comes from the IK, which checks it)
PLAN_FAILURES = {"timeout": "timeout", "start_in_collision": "collision", "goal_in_collision": "ik"}


@dataclass
class PlanResult:
    """A joint path (K, 3) from start to goal, or None with the ``failure`` ("timeout", "start_in_collision",
    "goal_in_collision"); ``planning_ms`` is the wall-clock time of the collision set-up and the OMPL solve."""

    path: np.ndarray | None
    planning_ms: float
    failure: str = ""


def tool_down(arm: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The six arm joints for q = [base, shoulder, elbow] with the wrists of the tool-down rule (``arm``: the
    current six, for wrist 3)."""
    arm = np.array(arm, dtype=float)
    arm[:3] = q
    arm[3] = -np.pi / 2 - q[1] - q[2]
    arm[4] = -np.pi / 2
    return arm


def densify(path: np.ndarray, step: float) -> np.ndarray:
    """``path`` (K, 3) with points inserted so that consecutive points differ by at most ``step`` in every joint."""
    points = [path[0]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        points.extend(a + (b - a) * k / n for k in range(1, n + 1))
    return np.array(points)


def thin(path: np.ndarray, step: float) -> np.ndarray:
    """The points of a finely spaced ``path`` (K, 3) worth a control step: from each kept point on, the last
    point within ``step`` of it in every joint (a longer segment stays whole, :func:`densify` splits it)."""
    kept = [0]
    for k in range(1, len(path)):
        if np.abs(path[k] - path[kept[-1]]).max() > step and k - 1 > kept[-1]:
            kept.append(k - 1)
    if kept[-1] != len(path) - 1:
        kept.append(len(path) - 1)
    return path[kept]


class CollisionChecker:
    """Validity of q = [base, shoulder, elbow] in a scratch copy of the scene as it is now.

    ``model`` is the scratch model of :meth:`RRTConnectMotion.scratch_model`; a contact closer than ``clearance``
    (at most the model's margin) is forbidden when the cell's rule forbids it (``held``: the product in the cup,
    moved with it) or when the cup touches a product other than ``target`` while nothing is held
    (:meth:`~hrc_lab.env.robot.cell.HRCCell.forbidden_contact` with ``pick_target=target``).
    """

    def __init__(self, env, model: mujoco.MjModel, held: int = -1, target: int = -1, clearance: float = 0.0) -> None:
        self.env, self.model, self.held, self.target, self.clearance = env, model, held, target, clearance
        self.scratch = env.scratch_state(model, held)
        self.data = self.scratch.data
        self.arm = env.commanded_qpos()
        joints = [model.joint(j).id for j in env.robots[0].robot_model.joints]
        self.low, self.high = model.jnt_range[joints[:4]].T
        held_geoms = env.object_geoms(held) if held >= 0 else frozenset()
        self.moving = np.zeros(model.ngeom, dtype=bool)
        self.moving[list(env.arm_geoms | env.cup_geoms | held_geoms)] = True
        self.products = np.array(sorted(env.object_geoms()))
        self.product_bits = np.where(np.isin(self.products, list(held_geoms)), 3, 0).astype(model.geom_contype.dtype)

    def collision(self, q: np.ndarray) -> str | None:
        """What makes q invalid ("joint-limit" or the forbidden contact), or None."""
        q = np.asarray(q, dtype=float)
        arm = tool_down(self.arm, q)
        if np.any(arm[:4] < self.low) or np.any(arm[:4] > self.high):
            return "joint-limit"
        model = self.model
        model.geom_contype[self.products] = self.product_bits  # a held product collides with everything,
        model.geom_conaffinity[self.products] = self.product_bits | 1  # resting ones with the robot only
        data = self.scratch.set_arm_qpos(arm)
        mujoco.mj_collision(model, data)
        n = data.ncon
        if n == 0:
            return None
        geoms = data.contact.geom[:n]
        near = (self.moving[geoms[:, 0]] | self.moving[geoms[:, 1]]) & (data.contact.dist[:n] < self.clearance)
        for a, b in geoms[near]:
            event = self.env.forbidden_contact(int(a), int(b), self.held, pick_target=self.target)
            if event:
                return event
        return None

    def valid(self, q: np.ndarray) -> bool:
        return self.collision(q) is None


def solve_rrt_connect(valid, low: np.ndarray, high: np.ndarray, q_start: np.ndarray, q_goal: np.ndarray,
                      cfg: RRTConnectConfig, seed: int) -> np.ndarray | None:
    """OMPL RRT-Connect from ``q_start`` to ``q_goal`` in the box [``low``, ``high``] with the state validity
    callable ``valid(q) -> bool``: the (simplified) path (K, d), or None when no exact solution was found within
    ``cfg.timeout_s``. Every OMPL object lives only in this call."""
    dim = len(low)
    previous = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)  # reseeding after the first solve logs an error; each solve makes its own samplers
    ou.RNG.setSeed(seed)
    ou.setLogLevel(ou.LOG_WARN)
    try:
        space = ob.RealVectorStateSpace(dim)
        bounds = ob.RealVectorBounds(dim)
        for i in range(dim):
            bounds.setLow(i, float(low[i]))
            bounds.setHigh(i, float(high[i]))
        space.setBounds(bounds)
        setup = og.SimpleSetup(space)
        setup.setStateValidityChecker(lambda state: bool(valid(np.array([state[i] for i in range(dim)]))))
        info = setup.getSpaceInformation()
        info.setStateValidityCheckingResolution(cfg.collision_resolution)
        planner = og.RRTConnect(info)
        if cfg.range_rad:
            planner.setRange(cfg.range_rad)
        setup.setPlanner(planner)
        start, goal = space.allocState(), space.allocState()
        for i in range(dim):
            start[i], goal[i] = float(q_start[i]), float(q_goal[i])
        setup.setStartAndGoalStates(start, goal)
        setup.solve(cfg.timeout_s)
        if not setup.haveExactSolutionPath():
            return None
        if cfg.simplify:
            setup.simplifySolution()
        return np.array([[s[i] for i in range(dim)] for s in setup.getSolutionPath().getStates()])
    finally:
        ou.setLogLevel(previous)


class RRTConnectMotion:
    """The motion module of RM+RRT-Connect: :meth:`run_stage` executes one picking or placing decision."""

    def __init__(self, cfg: RRTConnectConfig, seed: int = 0) -> None:
        self.cfg = cfg
        self.rng = np.random.default_rng(seed)
        self._source: mujoco.MjModel | None = None  # the live model the scratch model was copied from
        self._model: mujoco.MjModel | None = None
        self._planning_ms = 0.0  # of the stage being run

    # --- scene ------------------------------------------------------------------------------------------------

    def scratch_model(self, env) -> mujoco.MjModel:
        """A copy of ``env``'s model with contact margins of ``clearance_m`` on the arm, cup and products, its
        body poses synced with the live model (the cell moves its box per episode)."""
        live = env.mj_model
        if self._source is not live:
            model = copy.copy(live)
            robot = [g for g in env.arm_geoms | env.cup_geoms if model.body_weldid[model.geom_bodyid[g]] != 0]
            margined = robot + list(env.object_geoms())
            model.geom_margin[margined] = self.cfg.clearance_m
            model.body_margin[model.geom_bodyid[margined]] = self.cfg.clearance_m  # the broadphase's, per body
            # contact pairs: the moving robot (type 1, affinity 2) with everything (type 0, affinity 1) but the robot
            # and its mount (0, 2), which the cell allows; a held product (3, 3) with everything (set per checker)
            solid = (model.geom_contype | model.geom_conaffinity) > 0
            model.geom_contype[solid], model.geom_conaffinity[solid] = 0, 1
            fixed = list(env.arm_geoms | env.cup_geoms | env.mount_geoms)
            model.geom_contype[fixed], model.geom_conaffinity[fixed] = 0, 2
            model.geom_contype[robot], model.geom_conaffinity[robot] = 1, 2
            self._source, self._model = live, model
        self._model.body_pos[:] = live.body_pos
        self._model.body_quat[:] = live.body_quat
        return self._model

    def checker(self, env, held: int = -1, target: int = -1, clearance: float | None = None) -> CollisionChecker:
        """A collision checker of the scene as it is now; ``clearance`` defaults to ``cfg.clearance_m``."""
        clearance = self.cfg.clearance_m if clearance is None else clearance
        return CollisionChecker(env, self.scratch_model(env), held, target, clearance)

    # --- inverse kinematics and planning ------------------------------------------------------------------------

    def ik(self, env, lip_goal: np.ndarray, q_start: np.ndarray,
           checker: CollisionChecker | None = None) -> np.ndarray | None:
        """q = [base, shoulder, elbow] putting the lip at ``lip_goal``, by damped least squares from ``q_start``;
        None when it does not converge within ``ik_iterations`` to ``ik_tolerance_m`` or is in collision
        (``checker``; default: the scene now, with the product in the cup, at ``clearance_m``)."""
        cfg, arm = self.cfg, env.commanded_qpos()
        q = np.array(q_start[:3], dtype=float)
        for _ in range(cfg.ik_iterations):
            lip, jac = env.lip_kinematics(tool_down(arm, q))
            error = np.asarray(lip_goal) - lip
            if np.linalg.norm(error) < cfg.ik_tolerance_m:
                break
            dq = jac.T @ np.linalg.solve(jac @ jac.T + cfg.ik_damping**2 * np.eye(3), error)
            q += dq * min(1.0, IK_MAX_STEP / np.abs(dq).max())
        else:
            return None
        checker = checker or self.checker(env, held=env.suction.held)
        return q if checker.valid(q) else None

    def plan(self, env, q_start: np.ndarray, q_goal: np.ndarray, held: int = -1) -> PlanResult:
        """RRT-Connect from ``q_start`` to ``q_goal`` in the scene now, product ``held`` in the cup."""
        begin = time.perf_counter()
        checker = self.checker(env, held=held)
        failure, path = "", None
        if not checker.valid(q_start):
            failure = "start_in_collision"
        elif not checker.valid(q_goal):
            failure = "goal_in_collision"
        else:
            low, high = checker.low[:3], checker.high[:3]
            path = solve_rrt_connect(checker.valid, low, high, q_start, q_goal, self.cfg,
                                     int(self.rng.integers(1, 2**31 - 1)))
            failure = "" if path is not None else "timeout"
        return PlanResult(path, (time.perf_counter() - begin) * 1e3, failure)

    def straight(self, env, lip_goal: np.ndarray, checker: CollisionChecker) -> np.ndarray | None:
        """Joint path moving the lip on a straight line from where the command puts it to ``lip_goal``: IK
        waypoints every ``STRAIGHT_STEP_M``, each from the previous and checked by ``checker``, thinned to a point
        per control step (the lip strays < 0.5 mm from the line between them); None if one fails."""
        q = env.commanded_qpos()[:3]
        lip = env.lip_target_position()
        n = max(1, int(np.ceil(np.linalg.norm(lip_goal - lip) / STRAIGHT_STEP_M)))
        path = [q]
        for k in range(1, n + 1):
            q = self.ik(env, lip + (lip_goal - lip) * k / n, q, checker)
            if q is None:
                return None
            path.append(q)
        return thin(np.array(path), env.max_joint_step)

    # --- execution ----------------------------------------------------------------------------------------------

    def follow(self, env, path: np.ndarray, suction: bool, out: Rollout) -> bool:
        """Send the joint path as delta actions, at most ``max_joint_step`` per joint and step, relative to the
        commanded joints. False, with ``out.failure``, on a collision or at the horizon."""
        for target in densify(path, env.max_joint_step)[1:]:
            if not self._toward(env, target, suction, out):
                return False
        for _ in range(SETTLE_STEPS):  # where the cell held the command back (at most 2 steps ahead of the arm)
            if np.abs(path[-1] - env.commanded_qpos()[:3]).max() < 1e-9:
                break
            if not self._toward(env, path[-1], suction, out):
                return False
        return True

    def settle(self, env, suction: bool, out: Rollout) -> bool:
        """Hold still until the measured lip is within ``SETTLE_TOLERANCE`` of the commanded one (the servo lags
        about a step), at most ``SETTLE_STEPS`` steps."""
        for _ in range(SETTLE_STEPS):
            if np.linalg.norm(env.eef_position() - env.lip_target_position()) < SETTLE_TOLERANCE:
                break
            if not self._act(env, np.zeros(3), suction, out):
                return False
        return True

    def _toward(self, env, target: np.ndarray, suction: bool, out: Rollout) -> bool:
        dq = target - env.commanded_qpos()[:3]
        largest = np.abs(dq).max()
        if largest > env.max_joint_step:  # scaled, not clipped per joint: the arm stays on the path
            dq *= env.max_joint_step / largest
        return self._act(env, dq, suction, out)

    def _act(self, env, dq: np.ndarray, suction: bool, out: Rollout) -> bool:
        extra = [0.0] if env.yaw_action else []
        env.step(np.array([*dq, *extra, 1.0 if suction else -1.0]))
        out.steps += 1
        if env.collisions or env.done:
            out.failure = "collision" if env.collisions else "horizon"
            return False
        return True

    # --- stages -------------------------------------------------------------------------------------------------

    def run_stage(self, env, obj: int, stage: int, slot: int, out: Rollout) -> bool:
        """Pick product ``obj`` (stage PICK) or place it into goal slot ``slot`` (PLACE; the caller releases).
        Appends the stage's planning time (ms) to ``out.planning_ms`` and its steps to ``out.steps``; False, with
        ``out.failure`` one of "ik", "timeout", "collision", "pick", "horizon", when the stage failed."""
        half_z = env.cell_objects[obj].half_size[2]
        transit = env.table_offset[2] + env.transit_height + half_z
        self._planning_ms = 0.0
        if stage == PICK:
            done = self._pick(env, obj, env.object_positions()[obj] + np.array([0.0, 0.0, half_z]), transit, out)
        else:
            done = self._place(env, obj, env.episode.slot_positions[slot] + np.array([0.0, 0.0, half_z]), transit,
                               out)
        out.planning_ms.append(self._planning_ms)
        return done

    def _pick(self, env, obj: int, top: np.ndarray, transit: float, out: Rollout) -> bool:
        """Retreat if needed, RRT-Connect above ``top``, down onto it, grip, straight up to ``transit``."""
        if not (self._move(env, lambda: self._retreat(env), False, out)
                and self._move(env, lambda: self._transfer(env, top + [0.0, 0.0, self.cfg.hover_m], -1), False, out)
                and self._move(env, lambda: self._straight(env, top + [0.0, 0.0, PICK_LIP_ABOVE], target=obj), False,
                               out)
                and self.settle(env, False, out) and self._act(env, np.zeros(3), True, out)):
            return False
        if env.suction.held != obj:
            out.failure = "pick"
            return False
        lip = env.lip_target_position()
        return self._move(env, lambda: self._straight(env, np.array([lip[0], lip[1], transit]), held=obj), True, out)

    def _place(self, env, obj: int, top: np.ndarray, transit: float, out: Rollout) -> bool:
        """RRT-Connect, ``obj`` in the cup, to above ``top`` at ``transit``, then straight down onto it."""
        return (self._move(env, lambda: self._transfer(env, np.array([top[0], top[1], transit]), obj), True, out)
                and self._move(env, lambda: self._straight(env, top + [0.0, 0.0, PLACE_LIP_ABOVE], held=obj), True,
                               out)
                and self.settle(env, True, out))

    def _move(self, env, make_path, suction: bool, out: Rollout) -> bool:
        """Plan with ``make_path() -> (path or None, failure)``, timed as the stage's planning, then follow."""
        begin = time.perf_counter()
        path, failure = make_path()
        self._planning_ms += (time.perf_counter() - begin) * 1e3
        if path is None:
            out.failure = failure
            return False
        return self.follow(env, path, suction, out)

    def _retreat(self, env) -> tuple[np.ndarray | None, str]:
        """Straight up by ``hover_m`` when the command is within ``clearance_m`` of an obstacle (the cup at the
        product it just released), else stay."""
        q = env.commanded_qpos()[:3]
        if self.checker(env).valid(q):
            return q[None], ""
        return self._straight(env, env.lip_target_position() + [0.0, 0.0, self.cfg.hover_m])

    def _straight(self, env, lip_goal: np.ndarray, held: int = -1, target: int = -1) -> tuple[np.ndarray | None, str]:
        return self.straight(env, lip_goal, self.checker(env, held, target, clearance=0.0)), "ik"

    def _transfer(self, env, lip_goal: np.ndarray, held: int) -> tuple[np.ndarray | None, str]:
        """IK of ``lip_goal`` from the command and RRT-Connect there."""
        q_start = env.commanded_qpos()[:3]
        q_goal = self.ik(env, lip_goal, q_start, self.checker(env, held=held))
        if q_goal is None:
            return None, "ik"
        result = self.plan(env, q_start, q_goal, held)
        return result.path, PLAN_FAILURES.get(result.failure, "")


def build_rrt_connect(cfg: RRTConnectConfig, seed: int = 0, **_) -> RRTConnectMotion:
    """The RM+RRT-Connect motion module of a ``motion`` config (``MOTIONS.build(cfg, seed=...)``; the sub-goal
    planners' other arguments are ignored)."""
    return RRTConnectMotion(cfg, seed)
