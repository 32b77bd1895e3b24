"""The robot cells' recorder: a cell wrapper that renders every few control steps and writes the current decision
on the frame, as the text overlay of the thesis' Fig. 4.12 (the videos of Table 4.3, the demonstrations, the Ch.5
loop and Ch.6's robot row); files are written by :mod:`hrc_lab.data.video_io`."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")  # off-screen rendering on the CPU (or osmesa)


class FrameRecorder:
    """Stands in for a cell: ``step`` steps it, then every ``frame_skip``-th call renders ``camera`` with ``text``
    on the frame. Everything else is the cell's."""

    def __init__(self, cell, camera: str, width: int, height: int, frame_skip: int = 2) -> None:
        self.__dict__.update(cell=cell, camera=camera, width=width, height=height, frame_skip=frame_skip,
                             text="", frames=[], steps=0)

    def __getattr__(self, name: str):
        return getattr(self.cell, name)

    def step(self, action):
        result = self.cell.step(action)
        self.tick()
        return result

    def tick(self) -> None:
        """Count a control step the cell took and render every ``frame_skip``-th (for cells that step themselves,
        e.g. :attr:`hrc_lab.env.robot.clutter_cell.ClutterCell.on_step`)."""
        self.__dict__["steps"] += 1
        if self.steps % self.frame_skip == 0:
            self.frames.append(self.frame())

    def frame(self) -> np.ndarray:
        """The camera's RGB image now (rows top-down) with ``text`` in its top-left corner."""
        import cv2

        # robosuite's render draws into whichever GL context is current: another renderer in the process (the
        # clutter cell's scene camera) may have made its own current since
        self.cell.sim._render_context_offscreen.gl_ctx.make_current()
        image = np.flipud(self.cell.sim.render(camera_name=self.camera, width=self.width, height=self.height)).copy()
        if self.text:
            cv2.putText(image, self.text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 3, cv2.LINE_AA)
            cv2.putText(image, self.text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
        return image


def save_video(frames: list[np.ndarray], path: Path, fps: float) -> list[Path]:
    """``frames`` (RGB) as an MP4 at ``path`` and its four-frame strip beside it (``<stem>_strip.jpg``); both
    paths, for the run's artifacts."""
    from hrc_lab.data.video_io import write_strip, write_video

    if not frames:
        raise ValueError(f"{path.name}: no frame was rendered (the trial ended before the first frame)")
    strip = path.with_name(f"{path.stem}_strip.jpg")
    write_video(frames, path, fps)
    write_strip(frames, strip)
    return [path, strip]
