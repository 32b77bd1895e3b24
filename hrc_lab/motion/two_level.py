"""Training pairs from demonstrations and the closed-loop two-level execution (thesis 3.2, 4.2.2).

The sub-goal planner proposes a sub-goal from the observation and the task label; the neural dynamic planner
then acts for at most ``max_steps`` control steps (30 in the thesis) until the cup's lip is within ``tolerance``
of it; the next sub-goal is planned from where the arm ended. Suction is on in a picking stage from its second
sub-goal on (the cup grips the first top face its lip touches; during the first sub-goal the lip is still leaving
the part it just released) and through the placing stage, and off once the last placing sub-goal is done. The
cell applies a suction command before it moves the arm, so a Ch.3 picking stage, which ends at the top face, is
followed by one still step with suction on (as the expert does) before the grip is checked.

Labels: Ch.4 (Fig. 4.4) 0 = picking (l_pi), 1 + slot = placing into goal slot; the feature beside r is the
selected product's position when picking and the box position p when placing. Ch.3 (3.3): the stage label
0 pick blue, 1 place blue, 2 pick red, 3 place red; the observation is the three objects' positions and r.

r is the lip at the commanded joints (:meth:`~hrc_lab.env.robot.cell.HRCCell.lip_target_position`) wherever the
robot plans or acts from it; the measured lip, a control step behind, decides when a sub-goal is reached.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from hrc_lab.env.robot.cell import PICK, PLACE
from hrc_lab.motion.configs import PLANNER_INPUTS, STAGE_STARTS

RELEASE = np.array([0.0, 0.0, 0.0, -1.0])
GRIP = np.array([0.0, 0.0, 0.0, 1.0])
DESIGNED_SUBGOALS = 3  # Ch.4 sub-goals per stage (4.3)


# --- training pairs ---------------------------------------------------------------------------------------------


@dataclass
class SubgoalPairs:
    x: np.ndarray  # (N, d) observations
    labels: np.ndarray  # (N,) task label indices
    subgoals: np.ndarray  # (N, 3)
    groups: np.ndarray  # (N,) demo index, for grouped cross-validation
    indices: np.ndarray  # (N,) the sub-goal's index within its stage
    references: np.ndarray  # (N, 3) the stage's reference position (SubgoalConfig.relative_targets)


def package_pairs(demos) -> SubgoalPairs:
    """Ch.4 pairs (Fig. 4.4): one per designed sub-goal, x = [o_selected or p, r at the sub-goal's start]; the
    stage's reference is o_selected or p."""
    xs, labels, targets, groups, indices = [], [], [], [], []
    for k, demo in enumerate(demos):
        slot_of = {p: s for p, s in demo.episode["configuration"]}
        positions = demo.obs["object_pos"].reshape(len(demo), -1, 3)
        for label in np.unique(demo.stage_labels):
            obj, stage = divmod(int(label), 2)
            steps = np.flatnonzero(demo.stage_labels == label)
            feature = positions[steps[0], obj] if stage == PICK else demo.obs["box_pos"][steps[0]]
            for i in range(DESIGNED_SUBGOALS):
                at = steps[demo.subgoal_indices[steps] == i]
                if len(at) == 0:
                    continue
                xs.append(np.concatenate([feature, demo.obs["lip_target_pos"][at[0]]]))
                labels.append(0 if stage == PICK else 1 + slot_of[obj])
                targets.append(demo.subgoals[at[0]])
                groups.append(k)
                indices.append(i)
    x = np.array(xs)
    return SubgoalPairs(x, np.array(labels), np.array(targets), np.array(groups), np.array(indices), x[:, :3])


def correction_object(label: int) -> int:
    """The object Ch.3 stage ``label`` moves (3.3: 0 / 1 pick / place blue, 2 / 3 red): blue 1, red 2; green (0)
    is never moved."""
    return label // 2 + 1


def correction_reference(objects: np.ndarray, label: int) -> np.ndarray:
    """The reference position of Ch.3 stage ``label`` (``SubgoalConfig.relative_targets``): the part a picking
    stage picks; green, the goals' reference (Fig. 3.5), when placing."""
    objects = np.asarray(objects).reshape(-1, 3)
    return objects[correction_object(label)] if label % 2 == PICK else objects[0]


def grasp_shift(objects: np.ndarray, lip: np.ndarray, label: int) -> np.ndarray:
    """What a Ch.3 stage ``label``'s sub-goals are moved by so that the held part, not the lip, reaches them
    (``motion.place_through_grasp``): when placing, the lip's horizontal offset from the held part's centre
    (``objects``: the object positions now, ``lip``: the measured lip); zero when picking. The demonstrations grip
    each part at its centre, so a planned placing sub-goal is the lip's for a centred grip; a grip off the centre
    would put the part off the planned place by that offset. Not in the thesis."""
    if label % 2 == PICK:
        return np.zeros(3)
    offset = np.asarray(lip, dtype=float) - np.asarray(objects).reshape(-1, 3)[correction_object(label)]
    return np.array([offset[0], offset[1], 0.0])


def correction_input(objects: np.ndarray, r: np.ndarray, label: int, kind: str = "full") -> np.ndarray:
    """x of the Ch.3 sub-goal planner for stage ``label``: ``full`` (3.3) the three object positions and r;
    ``selected`` the position of the object the label names, green's (the goals' reference) and r, like Ch.4's
    reduced observation (o_selected, r); not in the thesis' Ch.3. Positions stay absolute (relative to r they
    are a linear map of the same numbers, and the planner's r jitter, ``SubgoalConfig.r_jitter_m``, moves r alone)."""
    if kind not in PLANNER_INPUTS:
        raise ValueError(f"planner input must be one of {list(PLANNER_INPUTS)}, got '{kind}'")
    objects = np.asarray(objects).reshape(-1, 3)
    if kind == "selected":
        objects = objects[[correction_object(label), 0]]
    return np.concatenate([objects.ravel(), r])


def correction_pairs(demos, starts: tuple[str, ...] = ("demonstrated",), planner_input: str = "full") -> SubgoalPairs:
    """Ch.3 pairs (3.3): per change-point stage, its re-sampled sub-goals, each planned from x = [3 object
    positions, r at the previous sub-goal] (or the ``planner_input`` of :func:`correction_input`), with the label
    of the detected stage. ``starts`` says where a stage's chain begins; with both, every stage gives two chains
    with the same targets:

    - ``demonstrated``: objects and the demonstrator's lip at the detected stage start. The change point falls
      after the expert has moved on (the lip leads the measured end effector by one step, a placed part is
      already lifted), so this r is 3-7 cm above where the previous stage ended.
    - ``executed``: as the closed loop starts the stage: r at the previous stage's last sub-goal, the objects at
      rest as they were when the part's picking stage began.

    The first misses the closed loop's starts (the second object's transit sub-goals then fall short); the second
    alone ties r to the part's position (every placing chain starts exactly at the part, so the two inputs are
    interchangeable and a grip 1 cm off the part's centre sends the plan elsewhere). Both together lowered
    Table 3.1 at the thesis' 20 demonstrations (issue 4's notes), so the default is the first.
    """
    if not starts or set(starts) - set(STAGE_STARTS):
        raise ValueError(f"stage starts must be a non-empty subset of {STAGE_STARTS}, got {list(starts)}")
    xs, labels, targets, groups, indices, references = [], [], [], [], [], []
    for k, demo in enumerate(demos):
        ended = demo.obs["lip_target_pos"][demo.stage_bounds[0][2]] if len(demo.stage_bounds) else None
        for (obj, stage, start, _), points in zip(demo.stage_bounds, demo.stage_subgoals):
            if stage == PICK:
                at_rest = demo.obs["object_pos"][start]
            chains = {"demonstrated": (demo.obs["object_pos"][start], demo.obs["lip_target_pos"][start]),
                      "executed": (at_rest, ended)}
            label = 2 * (obj - 1) + stage
            for objects, previous in (chains[name] for name in starts):
                for i, point in enumerate(points):
                    xs.append(correction_input(objects, previous, label, planner_input))
                    labels.append(label)
                    targets.append(point)
                    groups.append(k)
                    indices.append(i)
                    references.append(correction_reference(objects, label))
                    previous = point
            ended = points[-1]
    return SubgoalPairs(np.array(xs), np.array(labels), np.array(targets), np.array(groups), np.array(indices),
                        np.array(references))


def dynamics_pairs(demos, ndp) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(r_t, s_t, a_t) of every demonstrated step: the lip at the commanded joints (where the expert acted from;
    the measured lip lags a step behind, and a planner trained on it learns to stop short), a sub-goal and the
    expert's [base, shoulder, elbow] deltas (Delta = s - r, Eq. 3.5). ``ndp.targets`` (the
    :class:`~hrc_lab.motion.configs.NDPConfig`) names s: ``designed``, the sub-goal the expert was heading for;
    ``path``, the end effector ``h`` steps later for each ``h`` in ``ndp.path_steps`` within the same stage, with
    the expert's step at t as a_t (``ndp.path_action`` ``step``) or its mean step over those h steps (``mean``)."""
    if ndp.targets == "designed":
        r = np.concatenate([d.obs["lip_target_pos"] for d in demos])
        s = np.concatenate([d.subgoals for d in demos])
        a = np.concatenate([d.actions[:, :3] for d in demos])
        return r, s, a
    rs, ss, as_ = [], [], []
    for d in demos:
        done = np.cumsum(np.vstack([np.zeros((1, 3)), d.actions[:, :3]]), axis=0)  # joint motion before each step
        for h in ndp.path_steps:
            t = np.arange(len(d) - h)
            t = t[d.stage_labels[t] == d.stage_labels[t + h]]
            rs.append(d.obs["lip_target_pos"][t])
            ss.append(d.obs["robot0_eef_pos"][t + h])
            as_.append((done[t + h] - done[t]) / h if ndp.path_action == "mean" else d.actions[t, :3])
    return np.concatenate(rs), np.concatenate(ss), np.concatenate(as_)


def classifier_pairs(demos) -> tuple[np.ndarray, np.ndarray]:
    """Every step's raw observation (objects, r) and the expert's stage label, for c(x)."""
    x = np.concatenate([np.hstack([d.obs["object_pos"], d.obs["robot0_eef_pos"]]) for d in demos])
    return x, np.concatenate([d.stage_labels for d in demos])


# --- execution ----------------------------------------------------------------------------------------------------


@dataclass
class Rollout:
    success: bool = False
    steps: int = 0
    planning_ms: list[float] = field(default_factory=list)
    object_steps: dict[int, int] = field(default_factory=dict)  # object -> steps spent on it
    failure: str = ""
    picks: list[int] = field(default_factory=list)  # Ch.3: the object each picking stage went for, in order
    # Ch.3: the lip minus the picked object's top-face centre when each picking stage ended (before the grip), m
    pick_offsets: list[np.ndarray] = field(default_factory=list)
    # Ch.3: the stage's last planned sub-goal minus the same top-face centre, m (the planner's part of the offset)
    subgoal_offsets: list[np.ndarray] = field(default_factory=list)
    # Ch.3: at each picking stage's start, how far the objects moved before it are from their goals (worst), m
    moved_errors: list[float] = field(default_factory=list)
    subgoals: int = 0  # sub-goals the dynamic planner was sent to
    capped: int = 0  # of them, those it had not reached when their max_steps ran out

    def count(self, steps: int, status: str) -> None:
        """Book one :func:`reach`."""
        self.steps += steps
        self.subgoals += 1
        self.capped += status == CAPPED


REACHED, CAPPED, COLLISION, HORIZON = "reached", "capped", "collision", "horizon"


def capped_share(trials) -> float:
    """The share of the trials' sub-goals that ran out of steps (columns ``subgoals`` and ``capped``, one row per
    trial); NaN without sub-goals (RRT-Connect plans no sub-goals)."""
    total = int(trials.subgoals.sum())
    return float(trials.capped.sum() / total) if total else float("nan")


def reach(env, ndp, subgoal: np.ndarray, suction: bool, max_steps: int, tolerance: float) -> tuple[int, str]:
    """Act with the dynamic planner until the lip is within ``tolerance`` of ``subgoal``, for at most ``max_steps``.
    Returns (steps taken, status): ``reached``; ``capped`` when the steps ran out first (the thesis' 30-step cap:
    the caller plans its next sub-goal from where the arm is, and counts the cap); ``collision``; or ``horizon``
    when the episode ended. Only the last two end the trial."""
    command = 1.0 if suction else -1.0
    for step in range(max_steps):
        if np.linalg.norm(subgoal - env.eef_position()) < tolerance:
            return step, REACHED
        env.step(np.array([*ndp.act(env.lip_target_position(), subgoal), command]))
        if env.collisions:
            return step + 1, COLLISION
        if env.done:
            return step + 1, HORIZON
    return max_steps, REACHED if np.linalg.norm(subgoal - env.eef_position()) < tolerance else CAPPED


def picking_label(classifier, x: np.ndarray, rule: str) -> int:
    """The Ch.3 picking label (0 pick blue, 2 pick red) a stage starting at raw observation ``x`` (objects, r)
    goes for, by ``rule``: ``classifier``, the object of c(x)'s label, whichever stage it names; or
    ``picking_classifier``, c(x)'s most likely picking label (:meth:`~hrc_lab.motion.subgoal.StageClassifier.scores`).
    A placing stage has just ended there, and its last states, the part resting on its goal under the lip, are
    labelled as placing it in the demonstrations, so the first rule can send the arm back to that part."""
    if rule == "picking_classifier":
        return 2 * int(np.argmax(classifier.scores(x[None])[0][PICK::2]))
    if rule == "classifier":
        return 2 * (int(classifier(x[None])[0]) // 2)
    raise ValueError(f"picking label rule must be 'classifier' or 'picking_classifier', got '{rule}'")


def plan(planner, x: np.ndarray, label: int, index: int, reference: np.ndarray, timings: list[float]) -> np.ndarray:
    """The mean sub-goal for observation ``x``, stage ``label``, the sub-goal's ``index`` in its stage and the
    stage's ``reference`` position."""
    start = time.perf_counter()
    mean, _ = planner.predict(x[None], np.array([label]), np.array([index]), reference[None])
    timings.append((time.perf_counter() - start) * 1e3)
    return mean[0]


@dataclass
class TwoLevelMotion:
    """The motion module of Ch.4 (4.2.2): per stage, ``n_subgoals`` sub-goals planned from (o_selected or p, r)
    and the stage's label, each reached by the neural dynamic planner in at most ``max_steps`` steps."""

    planner: object
    ndp: object
    n_subgoals: int = DESIGNED_SUBGOALS
    max_steps: int = 30
    tolerance: float = 0.008

    def run_stage(self, env, obj: int, stage: int, slot: int, out: Rollout) -> bool:
        """Pick ``obj`` (stage PICK) or place it into goal slot ``slot`` (PLACE; the caller releases). False, with
        ``out.failure`` set, when the stage failed."""
        for i in range(self.n_subgoals):
            feature = env.object_positions()[obj] if stage == PICK else env.box_position()
            subgoal = plan(self.planner, np.concatenate([feature, env.lip_target_position()]),
                           0 if stage == PICK else 1 + slot, i, feature, out.planning_ms)
            steps, status = reach(env, self.ndp, subgoal, stage == PLACE or i > 0, self.max_steps, self.tolerance)
            out.count(steps, status)
            if status in (COLLISION, HORIZON):
                out.failure = status
                return False
        if stage == PICK and env.suction.held != obj:
            out.failure = "pick"
            return False
        return True


def run_package(env, motion: TwoLevelMotion) -> Rollout:
    """One package-to-order trial with ground-truth reasoning outputs (the expert's next product and its slot)."""
    env.reset()
    out = Rollout()
    for obj in env.expert_plan():
        slot = int(env.episode.goal_slot[obj])
        before = out.steps
        for stage in (PICK, PLACE):
            if not motion.run_stage(env, obj, stage, slot, out):
                return out
        env.step(RELEASE)
        out.steps += 1
        out.object_steps[obj] = out.steps - before
        if np.linalg.norm(env.object_positions()[obj] - env.goals[obj]) > env.success_threshold:
            out.failure = "placement"  # the trial has failed (Eq. 4.7); stop here
            return out
    out.success = bool(env.success())
    out.failure = "" if out.success else "placement"
    return out


def run_correction(env, planner, ndp, classifier, n_subgoals: int = 5, max_steps: int = 30,
                   tolerance: float = 0.008, stage_labels: str = "classifier",
                   planner_input: str = "full", place_through_grasp: bool = False, placement_oracle: bool = False,
                   manipulations: int | None = None) -> tuple[Rollout, np.ndarray]:
    """One error-correction trial: for each manipulation the case needs, the classifier c(x) labels the stage
    from the raw observation at its start (which object to pick), the placing stage of that object follows, and
    the planner proposes the sub-goals of each stage. ``stage_labels``: a rule of :func:`picking_label`, or
    ``ground_truth``: the expert's plan names the object to pick instead of c(x) (a diagnosis of the classifier,
    not the thesis' system); ``planner_input`` as the
    planner was trained (:func:`correction_input`); ``place_through_grasp``: placing sub-goals moved by the grip's
    offset (:func:`grasp_shift`); ``placement_oracle``: each released object is set exactly onto
    its goal before the next stage (a diagnosis of how a placement error propagates); ``manipulations``: stop after
    that many pick-and-place manipulations, the released part settled (DAgger's roll-in,
    :mod:`hrc_lab.motion.dagger`; default all the case needs). Returns the rollout (with the object each picking
    stage went for) and the final object positions."""
    env.reset()
    out = Rollout()
    label = 0
    order = env.expert_plan()
    for k in range(2 * (len(order) if manipulations is None else manipulations)):
        if k % 2 == 1:
            label += 1
        elif stage_labels == "ground_truth":
            label = env.stage_label(order[k // 2], PICK)
        else:
            label = picking_label(classifier, np.concatenate([env.object_positions().ravel(), env.eef_position()]),
                                  stage_labels)
        obj, stage = correction_object(label), label % 2
        if stage == PICK:
            errors = [np.linalg.norm(env.object_positions()[o] - env.goals[o]) for o in out.picks]
            out.moved_errors.append(float(max(errors, default=np.nan)))
            out.picks.append(obj)
        objects = env.object_positions().ravel()
        before = out.steps
        for i in range(n_subgoals):
            subgoal = plan(planner, correction_input(objects, env.lip_target_position(), label, planner_input), label,
                           i, correction_reference(objects, label), out.planning_ms)
            if place_through_grasp:
                subgoal = subgoal + grasp_shift(env.object_positions(), env.eef_position(), label)
            steps, status = reach(env, ndp, subgoal, stage == PLACE or i > 0, max_steps, tolerance)
            out.count(steps, status)
            if status in (COLLISION, HORIZON):
                out.failure = status
                return out, env.object_positions()
        if stage == PICK:  # the picking stage ends at the top face: hold still one step with suction on
            top = env.object_positions()[obj] + np.array([0.0, 0.0, env.cell_objects[obj].half_size[2]])
            out.pick_offsets.append(env.eef_position() - top)
            out.subgoal_offsets.append(subgoal - top)
            env.step(GRIP)
            out.steps += 1
            if env.suction.held != obj:
                out.failure = "pick"
                return out, env.object_positions()
        if stage == PLACE:
            env.step(RELEASE)
            out.steps += 1
            if placement_oracle:
                env.set_object_pose(obj, env.goals[obj])
                env.sim.forward()
        out.object_steps[obj] = out.object_steps.get(obj, 0) + out.steps - before
    settle(env)
    out.success = bool(env.success())
    return out, env.object_positions()


def settle(env, steps: int = 10) -> None:
    """Hold still with suction off until released parts have landed (0.5 s at 20 Hz), before scoring."""
    for _ in range(steps):
        if env.done:
            return
        env.step(RELEASE)
