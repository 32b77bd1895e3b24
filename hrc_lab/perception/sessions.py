"""Table 5.2 scoring of a whole assembly session streamed through Algorithm 3 (:mod:`hrc_lab.perception.pipeline`):
action detection (AD) per window, semantic guidance (SG) after every human placement and semantic control (SC) per
screw, against the session's true frame labels and steps (:func:`hrc_lab.env.assembly.video.render_session`), each
SG and SC event also marked *determined* when the true assembly so far leaves one right answer (no other goal
assembles the same parts there and wants another); with the robot cell (:mod:`hrc_lab.env.robot.assembly_cell`), the
robot's placements and the final assembly too."""

from __future__ import annotations

from typing import TYPE_CHECKING

from hrc_lab.env.assembly.spec import (
    SCREW,
    AssembleToOrderSpec,
    Scenario,
    action_labels,
    indistinguishable,
    next_object,
    parse_assembly,
    plan_tokens,
)
from hrc_lab.env.assembly.video import Clip, SessionStep
from hrc_lab.perception.hand_tracking import HandTracker
from hrc_lab.perception.pipeline import ActionPipeline, annotate
from hrc_lab.perception.robot_cell import CellHands, SideBySide
from hrc_lab.perception.windows import WindowStream
from hrc_lab.reasoning.hrc_loop import SemanticPlannerLoop

if TYPE_CHECKING:
    from hrc_lab.env.robot.assembly_cell import AssemblyCell
    from hrc_lab.env.robot.recorder import FrameRecorder
    from hrc_lab.perception.action_detector import ActionDetector


def segments_of(labels: list[str]) -> list[tuple[str, int, int]]:
    """Runs of equal frame labels: (label, start, end)."""
    runs, start = [], 0
    for k in range(1, len(labels) + 1):
        if k == len(labels) or labels[k] != labels[start]:
            runs.append((labels[start], start, k))
            start = k
    return runs


def checkpoints(clip: Clip, steps: list[SessionStep]) -> list[tuple[SessionStep, int, int]]:
    """(step, first frame of its placing or screwing segment, the frame the hand has left after it)."""
    runs = segments_of(clip.labels)
    decisive = [(i, r) for i, r in enumerate(runs) if r[0] == SCREW or parse_assembly(r[0])]
    if len(decisive) != len(steps):
        raise RuntimeError(f"session has {len(decisive)} placing/screwing segments for {len(steps)} steps")
    out = []
    for step, (i, (_, start, _)) in zip(steps, decisive):
        gap_end = runs[i + 1][2] if i + 1 < len(runs) and runs[i + 1][0] == "none" else runs[i][2]
        out.append((step, start, gap_end - 1))
    return out


def run_session(detector: ActionDetector, planner, spec: AssembleToOrderSpec, clip: Clip, steps: list[SessionStep],
                goal: int, complexity: int, annotated: list | None = None, cell: AssemblyCell | None = None,
                cell_view: FrameRecorder | None = None, recovery: bool = False) -> dict:
    """Stream one session through Algorithm 3 and score it: AD per window (majority label of its frames), SG at
    the end of the gap after every human placement (the guidance on screen against the truth), SC per screw (the
    first control command issued during it); ``sg_determined`` / ``sc_determined`` mark the events whose right
    answer the true assembly so far fixes (:func:`~hrc_lab.env.assembly.spec.indistinguishable`).

    Without ``cell`` the robot places what the video shows it placed, if it was asked. With the robot ``cell``
    (reset by the caller), every human placement the loop records puts the part there, and every Semantic Control
    command runs ``PickandPlace`` in the cell; a refused or failed one asks for help (its reason is kept) and the
    session goes on. The result then also holds ``placements`` and ``human`` (the cell's
    :class:`~hrc_lab.env.robot.assembly_cell.Placement` of each), ``latency_s`` (per executed command, from the
    start of the frame whose window triggered it to the robot's first motion command), the final ``assembly`` and
    ``complete`` (the bracket holds the goal). ``annotated`` with ``cell_view`` (a renderer of the cell): the
    worker's annotated frame beside the cell, and the robot's motion as extra frames while the worker's is held.
    ``recovery`` (with ``cell``; hrc_lab's, beyond Algorithm 3): the loop fixes recorded placements that contradict
    its inferred goal (:class:`~hrc_lab.reasoning.hrc_loop.SemanticPlannerLoop`); the result's ``recoveries``
    lists them and ``removals`` the parts the robot took back to their bins."""
    if recovery and cell is None:
        raise ValueError("recovery needs the robot cell: it is the robot that fixes a placement")
    cfg = detector.cfg
    marks = checkpoints(clip, steps)
    robot_jobs = {start: step.robot for step, start, _ in marks if step.kind == "screw"}
    frame_index = {"now": 0}

    def video_robot(part: str, position: int):
        due = [s for s in robot_jobs if s <= frame_index["now"] and robot_jobs[s] is not None]
        return robot_jobs.pop(due[-1]) if due else None

    side = SideBySide(cell_view, annotated) if cell_view is not None and annotated is not None else None
    hands = CellHands(cell, side) if cell is not None else None
    loop = SemanticPlannerLoop(planner, hands.robot if hands else video_robot, echo=None,
                               human=hands.human if hands else None, fix=hands.fix if recovery else None)
    stream = WindowStream(cfg.window, cfg.crop_size, cfg.frame_size, cfg.frame_stride)
    with HandTracker(model_complexity=complexity) as tracker:
        pipeline = ActionPipeline(detector, action_labels(spec), tracker, stream, loop)
        shown: dict[int, list] = {}
        due = {end: step for step, _, end in marks}
        for k, frame in enumerate(clip.frames):
            frame_index["now"] = k
            if hands is not None:
                hands.frame_started()
            state = pipeline.push(frame)
            if k in due:
                shown[k] = list(loop.pairs)
            if side is not None:
                side.add(annotate(frame, state, loop))
            elif annotated is not None:
                annotated.append(annotate(frame, state, loop))
    truth_assembled: set[int] = set()
    sg, sc, sg_determined, sc_determined = [], [], [], []
    for step, start, end in marks:
        before = Scenario(goal, frozenset(truth_assembled))
        if step.kind == "assemble":
            truth_assembled.add(step.position)
            now = Scenario(goal, frozenset(truth_assembled))
            plan = planner.plan([shown[end]])[0]
            sg.append(all(plan.guidance[t] == plan_tokens(spec, now, t) for t in spec.types))
            sg_determined.append(all(plan_tokens(spec, other, t) == plan_tokens(spec, now, t)
                                     for other in indistinguishable(spec, now) for t in spec.types))
        else:
            expected = next_object(spec, before)
            control = plan_tokens(spec, before, expected)
            events = [e for k, e in state.events if start <= k <= end and e.label == SCREW]
            sc.append(bool(events) and events[0].plan.next_object == expected and events[0].plan.control == control)
            sc_determined.append(all(next_object(spec, other) == expected
                                     and plan_tokens(spec, other, expected) == control
                                     for other in indistinguishable(spec, before)))
            truth_assembled.add(step.robot[1])
    ad = []
    for window in state.windows:
        labels = [x for x in clip.labels[window.start : window.end] if x != "none"]
        if labels:
            ad.append(window.label == max(set(labels), key=labels.count))
    result = {"ad": ad, "sg": sg, "sc": sc, "sg_determined": sg_determined, "sc_determined": sc_determined,
              "tracking_s": state.tracking_s, "classify_s": state.classify_s,
              "recoveries": [r for _, event in state.events for r in event.recoveries]}
    return {**result, **hands.result(spec.goal(goal))} if hands is not None else result
