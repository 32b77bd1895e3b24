"""Video files: :func:`read_video` reads the RGB frames of any video OpenCV opens, :func:`write_video` writes RGB
frames to an MP4 (``mp4v``) and :func:`write_strip` four of them side by side to a JPEG (for pages that cannot
play video). Used by the Ch.5 pipeline and the robot cells' videos (``data/render_demo``, Table 4.3)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from hrc_lab.data.files import DataFileError, existing_file


def read_video(path: Path) -> tuple[list[np.ndarray], int]:
    """The RGB frames and frame rate (15 when the file gives none) of a video; :class:`DataFileError` when the file
    is missing, not a video OpenCV opens, or holds no frame."""
    path = existing_file(path)
    capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        raise DataFileError(f"{path}: not a video OpenCV can open (another format, an unknown codec or corrupt?)")
    fps = int(round(capture.get(cv2.CAP_PROP_FPS))) or 15
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame[..., ::-1].copy())
    capture.release()
    if not frames:
        raise DataFileError(f"{path}: OpenCV read no frame from it (empty, truncated or an unknown codec?)")
    return frames, fps


def write_video(frames: list[np.ndarray], path: Path, fps: float) -> None:
    """The RGB ``frames`` as an MP4 at ``path``."""
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for frame in frames:
        writer.write(frame[..., ::-1])
    writer.release()


def write_strip(frames: list[np.ndarray], path: Path) -> None:
    """Four of the RGB ``frames``, evenly spaced from first to last, side by side as a JPEG at ``path``."""
    picks = np.linspace(0, len(frames) - 1, 4).astype(int)
    cv2.imwrite(str(path), np.hstack([frames[i] for i in picks])[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 80])
