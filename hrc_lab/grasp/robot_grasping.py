"""Algorithm 4 with the robot (Sec. 6.4.1, Fig. 6.8, Table 6.2 row "robot grasping"): image the scene, detect, build
the graph, run the single-image Algorithm 4 (:func:`hrc_lab.grasp.iterative.iterate`) and act on its answer in the
robot cell (:class:`~hrc_lab.env.robot.clutter_cell.ClutterCell`); repeat on the changed scene.

One robot iteration: render the camera image at the cell's part poses, detect and read the graph until the
single-image answer (a part to grasp, help, or none within ``grasp.max_iterations`` requests); grasp the part the
answer names at the 3-D point of its box (depth + camera model). A part of the requested type goes to the output
tray and the episode succeeds; any other part is put aside in a free spot outside the view, and the next iteration
starts from the new image. The episode ends with the delivery, help, no answer, a failed grasp, or after
``max_grasps`` grasps.

It succeeds when a part of the requested type is delivered, or when it ends in help on a scene where the rule's own
Algorithm 4 ends in help too. Otherwise its failure is the first of
:data:`~hrc_lab.grasp.diagnostics.ROBOT_FAILURES` that explains it:
the single-image causes of the answer that went wrong (:func:`hrc_lab.grasp.diagnostics.failure_cause`, judged
against the rule on the scene as it was then: ``detection``, ``graspability``, ``solution``, ``other``), ``slip``
(the gripper closed on the named part and nothing rose with it), ``collision`` (the gripper moved a neighbour by
more than :data:`DISTURBED` while grasping; the named part itself is no neighbour: a grasp that only pushed it is a
slip) and ``iteration_bound``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hrc_lab.env.robot.clutter_cell import ASIDE, TRAY, ClutterCell
from hrc_lab.grasp.diagnostics import failure_cause
from hrc_lab.grasp.iterative import iterate
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.grasp.solver import NodeReading

DISTURBED = 0.005  # m: a neighbour moved this far by a grasp counts as a collision


@dataclass
class RobotStep:
    """One robot iteration: what was decided on which image, what the gripper did, and where the time went."""

    requests: list[list[str]]  # the labels requested in turn on this image
    solutions: list[list[str]]
    action: str  # "grasp <type>", "help" or "none"
    right: bool  # the single-image answer agrees with the rule on this scene
    cause: str  # its failure cause when it does not
    held: str | None = None  # the type of the part that rose with the gripper
    disturbed: int = 0  # neighbours (parts other than the named one) the grasp moved by more than DISTURBED
    yaw_deg: float = 0.0  # the grasp's approach yaw (0: the rule's fingers closing along x)
    grip_mm: float = 0.0  # how far below the part's top the finger tips went
    seconds: dict[str, float] = field(default_factory=dict)  # render, detection, reasoning, motion (0: no grasp)


@dataclass
class RobotEpisode:
    goal: str
    steps: list[RobotStep]
    success: bool
    failure: str  # "" on success, else one of ROBOT_FAILURES


def run_episode(cell: ClutterCell, scene, spec, goal: str, perceive: Callable[[object], SceneNodes],
                read: Callable[[SceneNodes, np.ndarray], list[NodeReading]], max_requests: int,
                max_grasps: int, answer_right: Callable,
                on_decision: Callable[[RobotStep], None] | None = None, *, preshape: bool, choose_yaw: bool,
                yaw_order: str) -> RobotEpisode:
    """Algorithm 4 with the robot on ``scene`` (rendered from ``spec``) for the requested type ``goal``.
    ``perceive(scene_now)`` detects and matches (the trained detector,
    :func:`~hrc_lab.grasp.observation.scene_nodes`); ``read(nodes, mask)`` is the solver's reading of every node for
    a request; ``answer_right(nodes, goal, answer)`` scores a single-image answer against the rule;
    ``on_decision(step)`` sees each iteration's decision before the robot acts on it (a video's caption);
    ``preshape``: open the fingers only as wide as the named part needs (:meth:`ClutterCell.grasp_opening`), else
    fully; ``choose_yaw``: approach at the yaw whose finger volumes the depth image shows clearest
    (:meth:`ClutterCell.grasp_yaw`, the clear yaws ranked by ``yaw_order``), else with the rule's fingers closing
    along x."""
    cell.place_scene(scene, spec)
    steps: list[RobotStep] = []
    aside = 0
    for _ in range(max_grasps):
        start = time.perf_counter()
        now, shown = cell.current_scene(scene.seed)
        rendered = time.perf_counter()
        nodes = perceive(now)
        detected = time.perf_counter()
        readings: list[list[NodeReading]] = []

        def reading(mask, nodes=nodes, readings=readings):
            readings.append(read(nodes, mask))
            return readings[-1]

        answer = iterate(reading, nodes.boxes, nodes.labels, goal, max_requests)
        reasoned = time.perf_counter()
        right = answer_right(nodes, goal, answer)
        step = RobotStep(
            requests=[[nodes.labels[i] for i in r] for r in answer.requests],
            solutions=answer.solutions,
            action="help" if answer.help else "none" if answer.grasp is None else f"grasp {nodes.labels[answer.grasp]}",
            right=right,
            cause="" if right else failure_cause(nodes, goal, answer, readings),
            seconds={"render": rendered - start, "detection": detected - rendered, "reasoning": reasoned - detected,
                     "motion": 0.0},
        )
        steps.append(step)
        if on_decision is not None:
            on_decision(step)
        if answer.grasp is None:
            return RobotEpisode(goal, steps, answer.help and right, "" if answer.help and right else step.cause
                                or "other")
        before = cell.part_poses()[0]
        box = nodes.boxes[answer.grasp]
        point = cell.locate(box, now.depth)
        approach = cell.approach(box, now.depth, preshape, choose_yaw, yaw_order)
        step.yaw_deg = float(np.degrees(approach.yaw))
        step.grip_mm = float(1000 * (point[2] - approach.tips))
        outcome = cell.pick(point, approach.half_opening, approach.yaw, approach.tips)
        moved = np.linalg.norm(cell.part_poses()[0] - before, axis=1)
        named = shown[nodes.truth[answer.grasp]] if nodes.truth[answer.grasp] >= 0 else None  # the part it aimed at
        step.disturbed = int(sum(moved[j] > DISTURBED for j in outcome.touched if j != named))
        if outcome.held is None:
            step.seconds["motion"] = time.perf_counter() - reasoned
            return RobotEpisode(goal, steps, False, step.cause or ("collision" if step.disturbed else "slip"))
        step.held = cell.object_type(outcome.held)
        if step.held == goal:
            cell.put(TRAY, outcome.held)
        else:
            cell.put(ASIDE[aside % len(ASIDE)], outcome.held)
            aside += 1
        step.seconds["motion"] = time.perf_counter() - reasoned
        if step.held == goal:
            return RobotEpisode(goal, steps, True, "")
    first_wrong = next((s.cause for s in steps if s.cause), "")
    collided = next(("collision" for s in steps if s.disturbed), "")
    return RobotEpisode(goal, steps, False, first_wrong or collided or "iteration_bound")
