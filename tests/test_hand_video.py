"""The Ch.5 video side: MediaPipe on real and drawn hands, the generator's labels, windows, and the pipeline on a
short generated session."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from hrc_lab.env.assembly.hand_drawing import SKIN_TONES, HandPose, draw_hand, landmark_points
from hrc_lab.env.assembly.spec import SCREW, AssembleToOrderSpec, AssemblyVideoSpec, Scenario, action_labels
from hrc_lab.env.assembly.video import Layout, render_action_clip, render_session, session_script
from hrc_lab.perception.configs import ActionDetectorConfig
from hrc_lab.perception.hand_tracking import HandTracker
from hrc_lab.perception.pipeline import ActionPipeline
from hrc_lab.perception.sessions import checkpoints, segments_of
from hrc_lab.perception.windows import WindowStream, fill_track, hand_crop
from hrc_lab.reasoning.hrc_loop import SemanticPlannerLoop
from hrc_lab.reasoning.semantic_planner import Plan

FIXTURES = Path(__file__).parent / "fixtures" / "hands"
SPEC = AssembleToOrderSpec()
VIDEO = SPEC.video


@pytest.fixture(scope="module")
def tracker():
    with HandTracker(static_image_mode=True) as t:
        yield t


@pytest.mark.parametrize("photo", ["handSrc.jpg", "Back_Projection_Theory0.jpg", "Back_Projection1_Source_Image.jpg"])
def test_mediapipe_finds_real_hands(tracker, photo):
    image = cv2.imread(str(FIXTURES / photo))[..., ::-1].copy()
    observation = tracker(image)
    assert observation is not None
    assert observation.landmarks.shape == (21, 2)
    h, w = image.shape[:2]
    assert np.all((observation.position(w, h) > 0) & (observation.position(w, h) < 1))


def test_mediapipe_finds_no_hand_on_a_blank_frame(tracker):
    assert tracker(np.full((240, 320, 3), 128, np.uint8)) is None


def test_tracker_rejects_a_grey_frame(tracker):
    with pytest.raises(ValueError, match="RGB uint8"):
        tracker(np.zeros((240, 320), np.uint8))


def test_drawn_hand_is_tracked_where_it_is_drawn(tracker):
    """Every frame of a generated clip has the hand, and on a drawn frame MediaPipe's wrist and middle fingertip
    lie on the drawn ones."""
    clip = render_action_clip(SPEC, VIDEO, "o2->p3", seed=3)
    with HandTracker() as video_tracker:
        assert sum(video_tracker(frame) is not None for frame in clip.frames) >= 43
    frame = np.full((VIDEO.height, VIDEO.width, 3), (150, 140, 125), np.uint8)
    pose = HandPose((170.0, 220.0), 100.0, angle=10.0, curl=0.2)
    draw_hand(frame, pose, SKIN_TONES[2])
    observation = tracker(frame)
    truth = landmark_points(pose)
    for index in (0, 12):  # wrist, middle fingertip
        assert np.linalg.norm(observation.landmarks[index] - truth[index]) < 0.15 * pose.length


def test_action_clip_labels_and_end_point():
    clip = render_action_clip(SPEC, VIDEO, "o1->p4", seed=0)
    assert clip.frames.shape == (VIDEO.window, VIDEO.height, VIDEO.width, 3) and clip.frames.dtype == np.uint8
    assert set(clip.labels) == {"o1->p4"}
    target = Layout(VIDEO.width, VIDEO.height).position(4)
    assert np.linalg.norm(clip.grip[-1] - target) < 8  # the part is left at p4
    again = render_action_clip(SPEC, VIDEO, "o1->p4", seed=0)
    assert np.array_equal(clip.frames, again.frames)  # a seed fixes everything


def test_hand_pose_grip_point_and_landmarks():
    pose = HandPose.holding_at(np.array([100.0, 80.0]), 100.0, angle=20.0, curl=0.5)
    assert np.allclose(np.asarray(pose.wrist) + pose.grip_offset(), [100.0, 80.0])
    points = landmark_points(pose)
    assert points.shape == (21, 2) and np.allclose(points[0], pose.wrist)


def test_session_script_completes_the_goal_and_the_robot_places_the_experts_part():
    rng = np.random.default_rng(0)
    steps = session_script(SPEC, goal=1, rng=rng, p_screw=0.4)
    placed = [s.position if s.kind == "assemble" else s.robot[1] for s in steps]
    assert sorted(placed) == [1, 2, 3, 4, 5, 6]
    assembled: set[int] = set()
    for step in steps:
        if step.kind == "screw":
            assert step.position in assembled  # screws an assembled part
            assert step.robot[1] == min(set(range(1, 7)) - assembled)  # the expert's next position
            assert step.robot[0] == SPEC.goal(1)[step.robot[1] - 1]
        assembled.add(step.position if step.kind == "assemble" else step.robot[1])


def test_fill_track_and_crop_stay_inside():
    track = np.array([[np.nan, np.nan], [0.2, 0.4], [np.nan, np.nan], [0.4, 0.6]])
    assert np.allclose(fill_track(track), [[0.2, 0.4], [0.2, 0.4], [0.3, 0.5], [0.4, 0.6]])
    with pytest.raises(ValueError, match="no frame"):
        fill_track(np.full((3, 2), np.nan))
    frame = np.zeros((240, 320, 3), np.uint8)
    crop = hand_crop(frame, np.array([[300.0, 230.0], [340.0, 260.0]]), 64)  # landmarks beyond the frame
    assert crop.shape == (64, 64, 3)


def test_window_stream_closes_on_length_and_on_gaps():
    stream = WindowStream(window=10, crop_size=16, frame_size=16, frame_stride=3, gap=3, min_frames=4)
    frame = np.zeros((48, 64, 3), np.uint8)

    class Hand:  # a stand-in observation
        landmarks = np.array([[20.0, 20.0], [30.0, 30.0]])

        def position(self, w, h):
            return self.landmarks.mean(0) / [w, h]

    events = [stream.push(frame, Hand() if k < 16 or k >= 25 else None) for k in range(30)]
    closed = [(k, c) for k, (c, _) in enumerate(events) if c is not None]
    assert [c.start for _, c in closed] == [0, 10]  # a full window, then a short one cut by the gap
    assert closed[0][1].end == 10 and closed[1][1].end == 16
    assert closed[1][1].features.track.shape == (10, 2)  # front-padded
    finished = [f for _, f in events if f is not None]
    assert finished == [closed[1][1]] and not closed[0][1].finished  # only the window the hand left after


class TruthPlanner:
    """Plans from the true goal (the pipeline test checks perception and the loop, not the planner)."""

    def __init__(self, spec, goal):
        self.spec, self.goal = spec, goal

    def plan(self, pairs_list):
        from hrc_lab.env.assembly.spec import next_object, plan_tokens

        out = []
        for pairs in pairs_list:
            scenario = Scenario(self.goal, frozenset(p for _, p in pairs))
            full = len(scenario.assembled) == self.spec.n_positions
            nxt = self.spec.goal(self.goal)[0] if full else next_object(self.spec, scenario)
            out.append(Plan(self.goal, nxt, {t: plan_tokens(self.spec, scenario, t) for t in self.spec.types}))
        return out


def test_pipeline_on_a_short_generated_session():
    """Two positions, one human placement and one screw: with an oracle action detector the windows line up with
    the actions, the placement reaches the graph once the hand has left, and the screw makes the robot place the
    expert's part."""
    spec = AssembleToOrderSpec(product={"o1": 1, "o2": 1}, n_positions=2, goals=[["o1", "o2"]], n_goals=1,
                               allowed_positions={"o1": [1, 2], "o2": [1, 2]}, video=AssemblyVideoSpec())
    labels = action_labels(spec)
    seed = next(s for s in range(50) if [x.kind for x in session_script(spec, 0, np.random.default_rng(s), 0.9)]
                == ["assemble", "screw"])
    clip, steps = render_session(spec, spec.video, goal=0, seed=seed, p_screw=0.9, fast=False)
    assert [r[0] for r in segments_of(clip.labels) if r[0] != "none"][:4] == ["fetch", "transport",
                                                                             f"{steps[0].part}->p{steps[0].position}",
                                                                             SCREW]
    assert len(checkpoints(clip, steps)) == 2

    cfg = ActionDetectorConfig()
    stream = WindowStream(cfg.window, cfg.crop_size, cfg.frame_size, cfg.frame_stride)

    class OracleDetector:  # the majority true label of the window being classified
        def classify(self, track, crop, frames):
            window = stream.last
            true = [x for x in clip.labels[window.start : window.end] if x != "none"]
            return labels.index(max(set(true), key=true.count)), None

    placed = []
    loop = SemanticPlannerLoop(TruthPlanner(spec, 0), lambda part, p: placed.append((part, p)) or (part, p),
                               echo=None)
    loop.spec = spec
    with HandTracker() as tracker:
        pipeline = ActionPipeline(OracleDetector(), labels, tracker, stream, loop)
        for frame in clip.frames:
            state = pipeline.push(frame)
    assert [w.label for w in state.windows] == ["fetch", "transport", f"{steps[0].part}->p{steps[0].position}", SCREW]
    assert [e.label for _, e in state.events] == [f"{steps[0].part}->p{steps[0].position}", SCREW]
    assert placed == [steps[1].robot]
    assert loop.finished


def test_recovery_fixes_a_placement_that_contradicts_the_goal():
    """hrc_lab's recovery (beyond Algorithm 3): a recorded part the inferred goal does not want on its position is
    dropped, ``fix`` puts the goal's part there, the loop re-plans, and a position is fixed at most once; a worker's
    part recorded twice on one position is re-read; without ``fix`` (the thesis' loop) the wrong pairs stay."""
    from hrc_lab.env.robot.settings import AssembleToOrderConfig

    spec = AssembleToOrderConfig()  # goal 0: o3 o1 o1 o1 o2 o2
    fixes = []

    def fix(position, part):
        fixes.append((position, part))
        return part, position

    robot = lambda part, p: (part, p)  # noqa: E731 (a stand-in that places what it is told)
    thesis = SemanticPlannerLoop(TruthPlanner(spec, 0), robot, echo=None)
    thesis.run(["o1->p2", "o1->p3", "o2->p4"])
    assert thesis.pairs == [("o1", 2), ("o1", 3), ("o2", 4)]
    loop = SemanticPlannerLoop(TruthPlanner(spec, 0), robot, echo=None, fix=fix)
    *_, third = loop.run(["o1->p2", "o1->p3", "o2->p4"])
    assert fixes == [(4, "o1")] and loop.pairs == [("o1", 2), ("o1", 3), ("o1", 4)] and loop.contradictions(0) == []
    assert [(r.wrong, r.goal, r.wanted, r.placed) for r in third.recoveries] == [(("o2", 4), 0, "o1", ("o1", 4))]
    assert third.replan is not None and "recovery: p4 holds o2, goal g0 needs o1" in third.describe()
    loop.run(["o3->p4"])  # the same position contradicts again: it is not fixed a second time
    assert fixes == [(4, "o1")] and ("o3", 4) in loop.pairs
    # a goal that contradicts as many recorded pairs as it agrees with is not trusted to fix them
    lone = SemanticPlannerLoop(TruthPlanner(spec, 0), robot, echo=None, fix=fix)
    first, second = lone.run(["o2->p1", "o1->p2"])
    assert fixes == [(4, "o1")] and first.recoveries == [] == second.recoveries and lone.pairs[0] == ("o2", 1)
    # a worker's o1 recorded on p3 twice: the second is re-read as the nearest free position goal 0 wants o1 on
    loop = SemanticPlannerLoop(TruthPlanner(spec, 0), robot, echo=None, fix=fix)
    _, again = loop.run(["o1->p3", "o1->p3"])
    assert loop.pairs == [("o1", 3), ("o1", 2)] and again.label == "o1->p3"
    assert [(r.wrong, r.placed, r.reread) for r in again.recoveries] == [(("o1", 3), ("o1", 2), True)]
    assert "the worker's o1 read as p2" in again.describe() and again.replan is None  # its plan already reads p2
    thesis = SemanticPlannerLoop(TruthPlanner(spec, 0), robot, echo=None)
    thesis.run(["o1->p3", "o1->p3"])
    assert thesis.pairs == [("o1", 3), ("o1", 3)]


def test_the_loop_drives_the_robot_cell_on_a_short_session(monkeypatch):
    """Algorithm 3 with the robot (issue 21), oracle action detector: the worker's placement appears in the cell,
    the screw makes the robot pick and place the expert's part, the session ends with the goal assembled, and
    the side-by-side video holds the worker's frames plus the robot's motion."""
    from hrc_lab.env.robot.factory import make_env
    from hrc_lab.env.robot.recorder import FrameRecorder
    from hrc_lab.env.robot.settings import AssembleToOrderConfig
    from hrc_lab.perception import sessions

    spec = AssembleToOrderConfig(product={"o1": 1, "o2": 1}, n_positions=2, goals=[["o1", "o2"]], n_goals=1,
                                 allowed_positions={"o1": [1, 2], "o2": [1, 2]})
    seed = next(s for s in range(50) if [x.kind for x in session_script(spec, 0, np.random.default_rng(s), 0.9)]
                == ["assemble", "screw"])
    clip, steps = render_session(spec, spec.video, goal=0, seed=seed, p_screw=0.9, fast=False)
    labels = action_labels(spec)
    streams: list[WindowStream] = []

    class RecordedStream(WindowStream):  # the session's own stream, so that the oracle sees its windows
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            streams.append(self)

    class OracleDetector:  # the majority true label of the window being classified
        cfg = ActionDetectorConfig()

        def classify(self, track, crop, frames):
            window = streams[-1].last
            true = [x for x in clip.labels[window.start : window.end] if x != "none"]
            return labels.index(max(set(true), key=true.count)), None

    monkeypatch.setattr(sessions, "WindowStream", RecordedStream)
    cell = make_env(spec, seed=0, has_offscreen_renderer=True, camera_names="cellview", camera_heights=96,
                    camera_widths=128)
    view, frames = FrameRecorder(cell, "cellview", 128, 96, frame_skip=4), []
    result = sessions.run_session(OracleDetector(), TruthPlanner(spec, 0), spec, clip, steps, 0, 0, frames, cell,
                                  view)
    human, screw = steps
    assert [(p.part, p.position, p.success) for p in result["human"]] == [(human.part, human.position, True)]
    assert [(p.part, p.position, p.success) for p in result["placements"]] == [(*screw.robot, True)]
    assert result["complete"] and result["assembly"] == [("o1", 1), ("o2", 2)] and result["sc"] == [True]
    assert result["sg_determined"] == [True] and result["sc_determined"] == [True]  # one goal: every answer is fixed
    assert len(result["latency_s"]) == 1 and 0 < result["latency_s"][0] < 1.0
    moving = result["placements"][0].steps // 4
    assert len(frames) == len(clip.frames) + moving and frames[0].shape == (480, 640 + 640, 3)
    cell.close()


def test_a_video_without_a_hand_moves_no_robot():
    """A video where the hand never appears: no window, no plan, no robot command; the cell stays as it was."""
    from hrc_lab.env.robot.factory import make_env
    from hrc_lab.env.robot.settings import AssembleToOrderConfig
    from hrc_lab.perception.pipeline import annotate_frames
    from hrc_lab.perception.robot_cell import CellHands

    class NeverCalled:
        cfg = ActionDetectorConfig()

        def classify(self, *args):
            raise AssertionError("no window should close without a hand")

    spec = AssembleToOrderConfig()
    cell = make_env(spec, seed=0)
    hands = CellHands(cell)
    loop = SemanticPlannerLoop(TruthPlanner(spec, 0), hands.robot, echo=None, human=hands.human)
    frames = [np.full((VIDEO.height, VIDEO.width, 3), 128, np.uint8)] * 12
    out, state, seen = annotate_frames(NeverCalled(), action_labels(spec), loop, frames, 0, hands)
    assert seen == 0 and not state.windows and not state.events and len(out) == 12
    assert hands.placements == [] and hands.human_placements == [] and cell.assembly() == []
    cell.close()
