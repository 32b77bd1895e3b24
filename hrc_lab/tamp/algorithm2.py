"""Algorithm 2 (thesis 4.2): the reasoning module and a motion module in closed loop in the package-to-order cell.

At the start of every picking and placing stage the chain graph is built from the cell's structured observation
(:func:`stage_observation`; absent products have no node, 4.4.5), the reasoning module gives P_o and P_g, and the
decision is executed by a motion module with ``run_stage(env, obj, stage, slot, out) -> bool``: ours, the two-level
planner (:class:`~hrc_lab.motion.two_level.TwoLevelMotion`), or RRT-Connect
(:class:`~hrc_lab.motion.rrt_connect.RRTConnectMotion`). The next decision comes from the new observation, so a
wrong decision or a dropped product shows up as a failure, not as a skipped step.

Failures of a trial (the first one ends it):

- reasoning: ``wrong_stage`` (P_o names the packaging area while nothing is held, or a product while one is),
  ``wrong_object`` (a product that is not selected, already packed or absent), ``wrong_slot`` (P_g is not the
  held product's goal slot);
- motion: ``pick``, ``placement``, ``collision``, ``horizon`` (of the motion module), ``ik`` and ``timeout``
  (RRT-Connect), and ``stages`` when the stage budget runs out.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from hrc_lab.env.robot.cell import PICK, PLACE
from hrc_lab.env.robot.spec import StageObservation
from hrc_lab.motion.two_level import RELEASE, Rollout

REASONING_FAILURES = ("wrong_stage", "wrong_object", "wrong_slot")
STAGE_NAMES = {PICK: "pick", PLACE: "place"}


def stage_observation(env) -> StageObservation:
    """What the reasoning module sees now (Fig. 4.3): the cell's structured observation, with no ground truth
    (labels -1: they are what the module predicts)."""
    obs = env.structured_observation()
    held = int(obs["held"])
    return StageObservation(
        positions=obs["positions"], present=obs["present"], selected=obs["selected"], packed=obs["packed"],
        goal_slot=obs["goal_slot"], slot_positions=obs["slot_positions"], stage=PLACE if held >= 0 else PICK,
        target=held, held=held, order=int(obs["packed"].sum()), o_label=-1, g_label=-1, g_selected=np.zeros(3),
    )


@dataclass
class Decision:
    """One stage's decision: the stage the cell was in, P_o's and P_g's classes and what they mean."""

    stage: int
    o_class: int
    g_class: int
    product: int  # the product to pick (picking) or the held one (placing); -1 if none
    slot: int  # the goal slot to place into (placing); -1 when picking
    reasoning_ms: float
    failure: str = ""

    def text(self) -> str:
        """The plan as written on a video frame (Fig. 4.12's overlay)."""
        if self.stage == PICK:
            return f"pick product {self.product + 1}" if self.product >= 0 else "pick ?"
        return f"place product {self.product + 1} -> slot {self.slot + 1}"


@dataclass
class TampRollout(Rollout):
    decisions: list[Decision] = field(default_factory=list)
    object_planning_ms: dict[int, float] = field(default_factory=dict)  # product -> reasoning + motion planning
    collisions: list[str] = field(default_factory=list)  # the cell's forbidden contacts, e.g. "cup: ... / box_wall_n"


def decide(reasoner, env) -> Decision:
    """The reasoning module's decision at the start of a stage, checked against the cell's state."""
    obs = stage_observation(env)
    start = time.perf_counter()
    o_class, g_class = (int(v) for v in reasoner.predict([obs])[0])
    ms = (time.perf_counter() - start) * 1e3
    if obs.stage == PICK:
        product = o_class - 1
        decision = Decision(PICK, o_class, g_class, product, -1, ms)
        if o_class == 0 or g_class != 0:
            decision.failure = "wrong_stage"
        elif not (obs.selected[product] and obs.present[product] and not obs.packed[product]):
            decision.failure = "wrong_object"
        return decision
    decision = Decision(PLACE, o_class, g_class, obs.held, g_class - 1, ms)
    if o_class != 0 or g_class == 0:
        decision.failure = "wrong_stage"
    elif g_class - 1 != obs.goal_slot[obs.held]:
        decision.failure = "wrong_slot"
    return decision


def run_tamp(env, reasoner, motion, max_stages: int | None = None, on_decision=None) -> TampRollout:
    """One Algorithm 2 trial from ``env.reset()``: decide, act, observe, until every selected product is packed
    (success, Eq. 4.7) or a failure. ``max_stages`` defaults to two per product of the order; ``on_decision``
    (e.g. a video's overlay) is called with every decision before it is executed."""
    check_trained_for(reasoner, env)
    env.reset()
    out = TampRollout()
    budget = 2 * env.spec.n_selected if max_stages is None else max_stages
    started: dict[int, tuple[int, int]] = {}  # product -> (steps, planning entries) when its picking began
    for _ in range(budget):
        if all_packed(env):
            break
        decision = decide(reasoner, env)
        out.decisions.append(decision)
        if on_decision is not None:
            on_decision(decision)
        if decision.failure:
            out.failure = decision.failure
            return out
        obj = decision.product
        if decision.stage == PICK:
            started[obj] = (out.steps, len(out.planning_ms))
        steps0, plans0 = started.get(obj, (out.steps, len(out.planning_ms)))
        if not motion.run_stage(env, obj, decision.stage, decision.slot, out):
            out.collisions = list(env.collisions)
            return out
        if decision.stage == PLACE:
            env.step(RELEASE)
            out.steps += 1
            out.object_steps[obj] = out.steps - steps0
            own = [d.reasoning_ms for d in out.decisions[-2:]]
            out.object_planning_ms[obj] = float(sum(out.planning_ms[plans0:]) + sum(own))
            if np.linalg.norm(env.object_positions()[obj] - env.goals[obj]) > env.success_threshold:
                out.failure = "placement"
                return out
    out.success = bool(env.success())
    out.collisions = list(env.collisions)
    if not out.success:
        out.failure = "stages" if not all_packed(env) else ("collision" if env.collisions else "placement")
    return out


def check_trained_for(reasoner, env) -> None:
    """The reasoning module's P_o and P_g have m+1 and n_slots+1 classes: an order with more products or slots
    than it was trained for cannot be decided (4.4.5 retrains for a new order size), so it fails before the trial."""
    trained = getattr(reasoner, "spec", None)
    if trained is None:
        return
    for key, have, want in (("env.n_objects", env.spec.n_objects, trained.n_objects),
                            ("env.n_slots", env.spec.slots, trained.slots)):
        if have != want:
            raise ValueError(f"{key}: the cell has {have}, the reasoning module was trained for {want} "
                             f"(trained on {trained.cell}, tested on {env.spec.cell})")


def all_packed(env) -> bool:
    """Every selected product in its slot and nothing held (missing products count once restocked and packed)."""
    obs = env.structured_observation()
    return bool(obs["held"] < 0 and obs["present"].all() and obs["packed"][obs["selected"]].all())
