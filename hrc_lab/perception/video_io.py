"""Video files of the Ch.5 pipeline: :func:`read_video` reads the RGB frames of any video OpenCV opens and
:func:`write_video` writes RGB frames to an MP4 (``mp4v``)."""

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


def write_video(frames: list[np.ndarray], path: Path, fps: int) -> None:
    """The RGB ``frames`` as an MP4 at ``path``."""
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for frame in frames:
        writer.write(frame[..., ::-1])
    writer.release()
