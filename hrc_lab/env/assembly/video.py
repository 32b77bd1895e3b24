"""Generated top-down videos of the Ch.5 assembly cell (Sec. 5.3) with a rendered right hand (no recorded video of
the thesis exists to share, and nothing may be downloaded).

The cell: a pending area on the left with a bin per part type (o1 blue angle bracket, o2 orange block, o3 green
valve) and a screwdriver, and a steel bracket on the right with six numbered positions, p1 on the right to p6 on
the left (as in 5.3). A right hand (:mod:`hrc_lab.env.assembly.hand_drawing`) performs the 18 actions of Table 5.1 along
human-like paths: a minimum-jerk profile through a random via point, a slow wobble, per-frame jitter, a random start
delay and speed, and a hand that turns as it moves:

- ``fetch``: from a rest point or the bracket to a part bin, closing the fingers on a part;
- ``transport``: carrying a part from its bin to a hover point in front of the bracket;
- ``o_i->p_j``: from the hover point to position p_j, where the part is left;
- ``screw``: with the screwdriver from its rest to an assembled position, then turning it.

Every segment is ``window`` frames at ``fps`` (45 at 15 FPS in the thesis). A whole session (a goal, a random human
order, screw events after which the robot places the next part) is a chain of segments; the hand leaves the view
for a few frames after each placement and each screw (5.2.3: the worker moves the hand out of the detection
region). Fast sessions play each segment faster (fewer frames) and smear the hand along its motion: the thesis'
stated failure case. Skin tone, hand size, lighting, table colour and camera noise vary; a seed fixes everything.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from hrc_lab.env.assembly.hand_drawing import SKIN_TONES, HandPose, draw_hand
from hrc_lab.env.assembly.spec import (
    FETCH,
    SCREW,
    TRANSPORT,
    AssembleToOrderSpec,
    AssemblyVideoSpec,
    Scenario,
    next_object,
)

GENERATOR_VERSION = 2  # bump when a change to the drawing or the motions changes the clips (cached data sets)
TABLE_RGB = ((150, 140, 125), (128, 132, 126), (160, 130, 100), (112, 118, 128))
PART_RGB = {"o1": (40, 90, 200), "o2": (230, 120, 30), "o3": (40, 160, 70)}


@dataclass(frozen=True)
class Layout:
    """Pixel positions of the cell's furniture for a frame size (laid out on a 320 x 240 grid, then scaled)."""

    width: int
    height: int

    def _scale(self, x: float, y: float) -> np.ndarray:
        return np.array([x * self.width / 320.0, y * self.height / 240.0])

    def bin(self, part: str) -> np.ndarray:
        return self._scale(52, {"o1": 30, "o2": 76, "o3": 122}[part])

    def position(self, p: int) -> np.ndarray:
        return self._scale(280 - 29 * (p - 1), 92)

    def screwdriver(self) -> np.ndarray:
        return self._scale(54, 162)

    def hover(self, rng: np.random.Generator) -> np.ndarray:
        return self._scale(rng.uniform(150, 270), rng.uniform(125, 150))

    def rest(self, rng: np.random.Generator) -> np.ndarray:
        return self._scale(rng.uniform(140, 290), rng.uniform(150, 175))

    @property
    def unit(self) -> float:
        return self.width / 320.0


@dataclass
class CellState:
    """What lies in the cell: parts left in each bin and the part at each assembled position."""

    in_bins: dict[str, int]
    assembled: dict[int, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Segment:
    """One labelled action: where the grip point goes, what the hand holds, and how many frames it takes."""

    label: str
    start: tuple[float, float]
    end: tuple[float, float]
    held: str | None  # part type, "screwdriver" or None
    frames: int
    part: str | None = None  # the part fetched, carried or placed
    position: int | None = None  # the position placed at or screwed


@dataclass
class Clip:
    """Rendered frames (T, H, W, 3 RGB uint8), the label of every frame ("none" without a hand) and the true grip
    point of every frame (NaN without a hand)."""

    frames: np.ndarray
    labels: list[str]
    grip: np.ndarray


# -- drawing --------------------------------------------------------------------------------------------------------
def draw_part(img: np.ndarray, part: str, centre: np.ndarray, unit: float, angle: float = 0.0, light=1.0) -> None:
    rgb = tuple(int(min(255, c * light)) for c in PART_RGB[part])
    dark = tuple(int(c * 0.55) for c in rgb)
    c = np.asarray(centre, float)
    rot = np.array([[np.cos(np.deg2rad(angle)), -np.sin(np.deg2rad(angle))],
                    [np.sin(np.deg2rad(angle)), np.cos(np.deg2rad(angle))]])

    def poly(points):
        return np.round(c + unit * np.asarray(points, float) @ rot.T).astype(np.int32)

    if part == "o1":  # angle bracket
        cv2.fillPoly(img, [poly([[-9, -8], [9, -8], [9, -3], [-4, -3], [-4, 8], [-9, 8]])], rgb, cv2.LINE_AA)
        cv2.polylines(img, [poly([[-9, -8], [9, -8], [9, -3], [-4, -3], [-4, 8], [-9, 8]])], True, dark, 1, cv2.LINE_AA)
    elif part == "o2":  # block with two holes
        cv2.fillPoly(img, [poly([[-12, -5], [12, -5], [12, 5], [-12, 5]])], rgb, cv2.LINE_AA)
        for hole in poly([[-6, 0], [6, 0]]):
            cv2.circle(img, tuple(int(v) for v in hole), max(1, int(2 * unit)), dark, -1, cv2.LINE_AA)
    else:  # round valve with a cross handle
        cv2.circle(img, tuple(int(v) for v in np.round(c)), int(9 * unit), rgb, -1, cv2.LINE_AA)
        for a, b in (([-7, 0], [7, 0]), ([0, -7], [0, 7])):
            p, q = poly([a, b])
            cv2.line(img, tuple(int(v) for v in p), tuple(int(v) for v in q), dark, max(1, int(2 * unit)), cv2.LINE_AA)


def draw_screwdriver(img: np.ndarray, centre: np.ndarray, unit: float, angle: float = 0.0) -> None:
    a = np.deg2rad(angle - 90)
    d = np.array([np.cos(a), np.sin(a)])
    c = np.asarray(centre, float)
    tip, handle_end, joint = c + 14 * unit * d, c - 14 * unit * d, c + 2 * unit * d
    cv2.line(img, tuple(np.round(joint).astype(int)), tuple(np.round(tip).astype(int)), (170, 170, 175),
             max(1, int(2 * unit)), cv2.LINE_AA)
    cv2.line(img, tuple(np.round(handle_end).astype(int)), tuple(np.round(joint).astype(int)), (200, 40, 40),
             max(2, int(6 * unit)), cv2.LINE_AA)


def draw_cell(spec: AssemblyVideoSpec, state: CellState, table: tuple[int, int, int], light: float,
              screwdriver_on_table: bool = True) -> np.ndarray:
    """The cell without the hand, as an RGB frame."""
    layout = Layout(spec.width, spec.height)
    u = layout.unit
    img = np.empty((spec.height, spec.width, 3), np.uint8)
    gradient = np.linspace(0.88, 1.08, spec.width)[None, :, None] * light
    img[:] = np.clip(np.asarray(table, np.float32)[None, None, :] * gradient, 0, 255).astype(np.uint8)
    for part in ("o1", "o2", "o3"):  # bins with the parts left in them
        centre = layout.bin(part)
        top_left, bottom_right = centre - u * np.array([40, 20]), centre + u * np.array([40, 20])
        cv2.rectangle(img, tuple(np.round(top_left).astype(int)), tuple(np.round(bottom_right).astype(int)),
                      tuple(int(c * 0.7 * light) for c in table), -1)
        for k in range(state.in_bins.get(part, 0)):
            draw_part(img, part, centre + u * np.array([-26 + 26 * k, 0]), u, light=light)
    if screwdriver_on_table:
        draw_screwdriver(img, layout.screwdriver(), u, angle=90)
    left, right = layout.position(6) - u * np.array([18, 9]), layout.position(1) + u * np.array([18, 9])
    cv2.rectangle(img, tuple(np.round(left).astype(int)), tuple(np.round(right).astype(int)),
                  tuple(int(min(255, 175 * light)) for _ in range(3)), -1)
    for p in range(1, 7):
        centre = layout.position(p)
        cv2.circle(img, tuple(np.round(centre).astype(int)), max(1, int(3 * u)), (60, 60, 65), -1, cv2.LINE_AA)
        cv2.putText(img, str(p), tuple(np.round(centre + u * np.array([-3, 20])).astype(int)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.3 * u, (30, 30, 30), 1, cv2.LINE_AA)
        if p in state.assembled:
            draw_part(img, state.assembled[p], centre, u, light=light)
    return img


# -- motion ---------------------------------------------------------------------------------------------------------
def human_path(start, end, frames: int, speed: float, rng: np.random.Generator, spec: AssemblyVideoSpec,
               ) -> tuple[np.ndarray, np.ndarray]:
    """Grip-point path (frames, 2) and motion progress (frames,) in [0, 1]: a random start delay, then a
    minimum-jerk move lasting 0.65 x window / speed frames through a via point off the straight line, a slow wobble
    that fades at both ends, per-frame jitter, and the hand holding still at the end."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    duration = max(4, int(round(0.65 * spec.window / speed)))
    delay = int(rng.integers(0, max(1, frames - duration - 1)))
    t = np.clip((np.arange(frames) - delay) / duration, 0.0, 1.0)
    progress = 10 * t**3 - 15 * t**4 + 6 * t**5
    normal = np.array([-(end - start)[1], (end - start)[0]])
    via = rng.normal(0.0, 0.12) * normal
    bend = 4 * progress * (1 - progress)
    envelope = np.sin(np.pi * progress)[:, None]
    phase, freq = rng.uniform(0, 2 * np.pi, 2), rng.uniform(0.1, 0.25, 2)
    wobble = spec.wobble_px * envelope * np.stack([np.sin(freq[0] * np.arange(frames) + phase[0]),
                                                   np.cos(freq[1] * np.arange(frames) + phase[1])], 1)
    jitter = rng.normal(0.0, spec.jitter_px, (frames, 2))
    path = start + progress[:, None] * (end - start) + bend[:, None] * via + wobble + jitter
    return path, progress


def render_segment(spec: AssemblyVideoSpec, segment: Segment, state: CellState, look: dict,
                   rng: np.random.Generator, speed: float, motion_blur: bool) -> Clip:
    """Render one segment from ``state``; ``state`` is updated at its end (a placed part lands on the bracket)."""
    layout = Layout(spec.width, spec.height)
    path, progress = human_path(segment.start, segment.end, segment.frames, speed, rng, spec)
    base_angle = look["angle"] + rng.uniform(-8, 8)
    screwdriver_away = segment.held == "screwdriver"
    frames = []
    scene = draw_cell(spec, state, look["table"], look["light"], not screwdriver_away)
    for k in range(segment.frames):
        s = progress[k]
        img = scene.copy()
        angle = base_angle + 12 * (s - 0.5)
        curl = 0.6 if segment.held else 0.15
        if segment.label == FETCH:
            curl = 0.15 + 0.45 * max(0.0, (s - 0.8) / 0.2)
        held = segment.held
        if segment.label == SCREW and s >= 1.0:  # turning the screwdriver once it is at the position
            twist_start = int(np.argmax(progress >= 1.0))
            angle += 22 * np.sin(2 * np.pi * (k - twist_start) / 8.0)
        if segment.label == FETCH and s >= 0.9:
            held = segment.part
        pose = HandPose.holding_at(path[k], look["length"], angle, curl)
        if held == "screwdriver":
            draw_screwdriver(img, path[k], layout.unit, angle)
        elif held is not None:
            draw_part(img, held, path[k], layout.unit, angle, look["light"])
        motion = tuple(path[k] - path[k - 1]) if (motion_blur and k) else (0.0, 0.0)
        draw_hand(img, pose, look["skin"], look["light"], spec.hand_blur, motion)
        frames.append(img)
    if segment.position is not None and segment.label not in (SCREW,):
        state.assembled[segment.position] = segment.part
    return Clip(np.stack(frames), [segment.label] * segment.frames, path)


def empty_frames(spec: AssemblyVideoSpec, state: CellState, look: dict, n: int) -> Clip:
    """``n`` frames of the cell without a hand."""
    scene = draw_cell(spec, state, look["table"], look["light"])
    return Clip(np.repeat(scene[None], n, 0), ["none"] * n, np.full((n, 2), np.nan))


def add_noise(frames: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    if sigma <= 0:
        return frames
    noise = rng.normal(0.0, sigma, frames.shape).astype(np.float32)
    return np.clip(frames.astype(np.float32) + noise, 0, 255).astype(np.uint8)


def sample_look(spec: AssemblyVideoSpec, rng: np.random.Generator) -> dict:
    """Appearance of one clip or session: skin tone, hand size and posture, light, table colour."""
    return {
        "skin": SKIN_TONES[int(rng.integers(len(SKIN_TONES)))],
        "length": float(rng.uniform(*spec.hand_length)),
        "light": float(rng.uniform(*spec.light)),
        "table": TABLE_RGB[int(rng.integers(len(TABLE_RGB)))],
        "angle": float(rng.uniform(-12, 12)),
    }


# -- labelled action clips (Fig. 5.5 / 5.6 data) -------------------------------------------------------------------
def random_state(ato: AssembleToOrderSpec, rng: np.random.Generator, keep_free: int | None = None,
                 keep_assembled: int | None = None) -> CellState:
    """A random partially assembled product of a random goal, with ``keep_free`` unassembled and ``keep_assembled``
    assembled; the bins hold what is left."""
    goal = ato.goal(int(rng.integers(len(ato.goals))))
    positions = [p for p in range(1, ato.n_positions + 1) if p != keep_free]
    chosen = {p for p in positions if rng.random() < 0.5 and p != keep_assembled}
    if keep_assembled is not None:
        chosen.add(keep_assembled)
    assembled = {p: goal[p - 1] for p in chosen}
    in_bins = {t: n - sum(1 for v in assembled.values() if v == t) for t, n in ato.product.items()}
    return CellState(in_bins={t: max(n, 1) for t, n in in_bins.items()}, assembled=assembled)


def action_segment(ato: AssembleToOrderSpec, spec: AssemblyVideoSpec, label: str, rng: np.random.Generator,
                   frames: int) -> tuple[Segment, CellState]:
    """A standalone segment of ``label`` in a random cell state, for the action-classification data set."""
    layout = Layout(spec.width, spec.height)
    part = str(rng.choice(ato.types))
    if label == FETCH:
        state = random_state(ato, rng)
        start = layout.rest(rng) if rng.random() < 0.5 else layout.position(int(rng.integers(1, 7)))
        end = layout.bin(part) + rng.normal(0, 3 * layout.unit, 2)
        return Segment(FETCH, tuple(start), tuple(end), None, frames, part=part), state
    if label == TRANSPORT:
        state = random_state(ato, rng)
        return Segment(TRANSPORT, tuple(layout.bin(part)), tuple(layout.hover(rng)), part, frames, part=part), state
    if label == SCREW:
        position = int(rng.integers(1, ato.n_positions + 1))
        state = random_state(ato, rng, keep_assembled=position)
        end = layout.position(position) + rng.normal(0, 2 * layout.unit, 2)
        return Segment(SCREW, tuple(layout.screwdriver()), tuple(end), "screwdriver", frames, position=position), state
    part, position = label.split("->p")
    position = int(position)
    state = random_state(ato, rng, keep_free=position)
    end = layout.position(position) + rng.normal(0, 1.5 * layout.unit, 2)
    segment = Segment(label, tuple(layout.hover(rng)), tuple(end), part, frames, part=part, position=position)
    return segment, state


def render_action_clip(ato: AssembleToOrderSpec, spec: AssemblyVideoSpec, label: str, seed: int) -> Clip:
    """One labelled ``window``-frame clip of ``label`` (Table 5.1), fully determined by ``seed``."""
    rng = np.random.default_rng(seed)
    look = sample_look(spec, rng)
    segment, state = action_segment(ato, spec, label, rng, spec.window)
    clip = render_segment(spec, segment, state, look, rng, float(rng.uniform(*spec.speed)), motion_blur=False)
    clip.frames = add_noise(clip.frames, spec.camera_noise, rng)
    return clip


# -- whole sessions (Table 5.2) -------------------------------------------------------------------------------------
@dataclass
class SessionStep:
    """A human assembly (fetch, transport, place) or a screw after which the robot places ``robot`` = (part, p)."""

    kind: str  # "assemble" or "screw"
    part: str
    position: int
    robot: tuple[str, int] | None = None


def session_script(ato: AssembleToOrderSpec, goal: int, rng: np.random.Generator, p_screw: float) -> list[SessionStep]:
    """The human assembles the goal's positions in a random order and now and then screws instead, which hands
    the next part (the expert's choice, 5.3) to the robot; the session ends when the product is complete."""
    assembled: set[int] = set()
    steps: list[SessionStep] = []
    target = ato.goal(goal)
    while len(assembled) < ato.n_positions:
        if assembled and rng.random() < p_screw:
            screwed = int(rng.choice(sorted(assembled)))
            part = next_object(ato, Scenario(goal, frozenset(assembled)))
            position = min(set(range(1, ato.n_positions + 1)) - assembled)
            steps.append(SessionStep("screw", target[screwed - 1], screwed, robot=(part, position)))
            assembled.add(position)
        else:
            position = int(rng.choice(sorted(set(range(1, ato.n_positions + 1)) - assembled)))
            steps.append(SessionStep("assemble", target[position - 1], position))
            assembled.add(position)
    return steps


def render_session(ato: AssembleToOrderSpec, spec: AssemblyVideoSpec, goal: int, seed: int, p_screw: float,
                   fast: bool) -> tuple[Clip, list[SessionStep]]:
    """A whole assembly session as one clip: per human assembly fetch -> transport -> o->p then the hand leaves
    the view; per screw the screwing motion, the hand leaves, and the robot's part appears on the bracket."""
    rng = np.random.default_rng(seed)
    layout = Layout(spec.width, spec.height)
    steps = session_script(ato, goal, rng, p_screw)  # first, so that a seed's script is session_script's
    look = sample_look(spec, rng)
    state = CellState(in_bins=dict(ato.product))
    clips = [empty_frames(spec, state, look, int(rng.integers(*spec.gap_frames)))]
    here = layout.rest(rng)

    def play(segment_label, start, end, held, part=None, position=None):
        speed = float(rng.uniform(*(spec.fast_speed if fast else spec.speed)))
        frames = int(round(spec.window / speed)) if fast else spec.window
        segment = Segment(segment_label, tuple(start), tuple(end), held, frames, part=part, position=position)
        clip = render_segment(spec, segment, state, look, rng, speed, motion_blur=fast)
        clips.append(clip)
        return clip.grip[-1]

    for step in steps:
        if step.kind == "assemble":
            here = play(FETCH, here, layout.bin(step.part) + rng.normal(0, 3 * layout.unit, 2), None, step.part)
            state.in_bins[step.part] -= 1
            here = play(TRANSPORT, here, layout.hover(rng), step.part, step.part)
            end = layout.position(step.position) + rng.normal(0, 1.5 * layout.unit, 2)
            play(f"{step.part}->p{step.position}", here, end, step.part, step.part, step.position)
        else:
            end = layout.position(step.position) + rng.normal(0, 2 * layout.unit, 2)
            play(SCREW, layout.screwdriver(), end, "screwdriver", position=step.position)
            part, position = step.robot
            state.in_bins[part] -= 1
            state.assembled[position] = part
        clips.append(empty_frames(spec, state, look, int(rng.integers(*spec.gap_frames))))
        here = layout.rest(rng)
    frames = add_noise(np.concatenate([c.frames for c in clips]), spec.camera_noise, rng)
    clip = Clip(frames, [label for c in clips for label in c.labels], np.concatenate([c.grip for c in clips]))
    return clip, steps
