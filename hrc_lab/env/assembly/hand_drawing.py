"""A right hand seen from above (back of the hand, fingers pointing away from the worker), drawn with OpenCV so
that MediaPipe's hand model detects it: rounded fingers, finger creases and nails, a shading gradient, a soft edge.

The hand is defined in its own frame, in units of the hand length (wrist to middle fingertip), fingers along -y
and the thumb on the -x side (a right hand, palm down, seen from above). :class:`HandPose` places it in the image:
wrist position, length in pixels, rotation, and how far the fingers are curled around a held object.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# (knuckle x, knuckle y, length, splay in degrees from -y, width) per finger, in hand lengths; thumb first
_FINGERS = (
    (-0.20, -0.16, 0.36, -52.0, 0.13),  # thumb, from its base on the palm
    (-0.155, -0.47, 0.47, -7.0, 0.095),  # index
    (-0.05, -0.50, 0.50, -1.0, 0.10),  # middle
    (0.055, -0.48, 0.46, 5.0, 0.095),  # ring
    (0.15, -0.43, 0.37, 12.0, 0.085),  # little
)
_PALM = np.array([[-0.19, 0.02], [0.17, 0.02], [0.205, -0.40], [0.10, -0.51], [-0.05, -0.53], [-0.21, -0.48]])
#: RGB skin tones from light to dark, sampled by the video generator
SKIN_TONES = ((236, 200, 175), (224, 172, 140), (198, 145, 110), (170, 120, 90), (141, 95, 66), (105, 70, 50))


@dataclass(frozen=True)
class HandPose:
    """Where and how the hand is drawn: wrist pixel, hand length (px), rotation (deg, positive turns the fingers
    clockwise in the image) and curl (0 open, 1 fingers folded to ~60 % of their length around a part)."""

    wrist: tuple[float, float]
    length: float
    angle: float = 0.0
    curl: float = 0.0

    def to_image(self, points: np.ndarray) -> np.ndarray:
        """Hand-frame points (N, 2) -> image pixels (N, 2)."""
        a = np.deg2rad(self.angle)
        rotation = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        return np.asarray(self.wrist, float) + self.length * points @ rotation.T

    def grip_offset(self) -> np.ndarray:
        """Pixel offset from the wrist to the point just beyond the fingertips where a held part sits (pinched by
        the fingertips, so that the camera above sees it)."""
        return self.to_image(np.array([[-0.08, -1.17 + 0.2 * self.curl]]))[0] - np.asarray(self.wrist, float)

    @classmethod
    def holding_at(cls, grip: np.ndarray, length: float, angle: float, curl: float) -> HandPose:
        """The pose whose grip point is ``grip``."""
        probe = cls((0.0, 0.0), length, angle, curl)
        return cls(tuple(np.asarray(grip, float) - probe.grip_offset()), length, angle, curl)


def _finger_joints(pose: HandPose) -> list[np.ndarray]:
    """The 4 joints (knuckle ... tip) of each finger in the hand frame; curled fingers look shorter from above."""
    joints = []
    for i, (x, y, length, splay, _) in enumerate(_FINGERS):
        direction = np.array([np.sin(np.deg2rad(splay)), -np.cos(np.deg2rad(splay))])
        shrink = 1.0 - (0.25 if i == 0 else 0.4) * pose.curl
        steps = np.array([0.0, 0.45, 0.75, 1.0]) * length * shrink
        joints.append(np.array([x, y]) + steps[:, None] * direction)
    return joints


def _pt(p: np.ndarray) -> tuple[int, int]:
    return int(round(p[0])), int(round(p[1]))


def draw_hand(frame: np.ndarray, pose: HandPose, skin_rgb: tuple[int, int, int], light: float = 1.0,
              blur: int = 9, motion: tuple[float, float] = (0.0, 0.0)) -> None:
    """Composite the hand onto ``frame`` (RGB uint8, in place). ``blur`` is the Gaussian kernel of the hand layer
    (the recipe MediaPipe detects); ``motion`` (px per frame) smears it along the motion, as a fast hand on camera.
    Only the hand's bounding box is processed."""
    h, w = frame.shape[:2]
    margin = int(0.15 * pose.length) + blur + int(np.hypot(*motion)) + 2
    outline = pose.to_image(np.vstack([_PALM, *_finger_joints(pose)]))
    x0, y0 = np.floor(outline.min(0)).astype(int) - margin
    x1, y1 = np.ceil(outline.max(0)).astype(int) + margin
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 <= x0 or y1 <= y0:
        return
    local = HandPose((pose.wrist[0] - x0, pose.wrist[1] - y0), pose.length, pose.angle, pose.curl)
    colour, alpha = _hand_layer((y1 - y0, x1 - x0), local, skin_rgb, light)
    if blur > 1:
        colour, alpha = cv2.GaussianBlur(colour, (blur, blur), 0), cv2.GaussianBlur(alpha, (blur, blur), 0)
    steps = int(round(np.hypot(*motion)))
    if steps > 1:
        kernel = np.zeros((2 * steps + 1, 2 * steps + 1), np.float32)
        direction = np.asarray(motion) / np.hypot(*motion)
        cv2.line(kernel, _pt(steps - steps * direction), _pt(steps + 0 * direction), 1.0, 1)
        kernel /= kernel.sum()
        premultiplied = colour.astype(np.float32) * alpha[..., None]
        alpha = cv2.filter2D(alpha, -1, kernel)
        colour = cv2.filter2D(premultiplied, -1, kernel) / np.maximum(alpha[..., None], 1e-3)
    region = frame[y0:y1, x0:x1].astype(np.float32)
    a = alpha[..., None]
    frame[y0:y1, x0:x1] = np.clip(region * (1 - a) + colour.astype(np.float32) * a, 0, 255).astype(np.uint8)


def _hand_layer(shape: tuple[int, int], pose: HandPose, skin_rgb, light: float) -> tuple[np.ndarray, np.ndarray]:
    """The hand's RGB colour image and its alpha mask (float32 in [0, 1]) in a box of ``shape`` (h, w)."""
    mask = np.zeros(shape, np.uint8)
    scale = pose.length
    cv2.fillPoly(mask, [np.round(pose.to_image(_PALM)).astype(np.int32)], 255, lineType=cv2.LINE_AA)
    fingers = [pose.to_image(joints) for joints in _finger_joints(pose)]
    widths = [max(2, int(round(f[4] * scale))) for f in _FINGERS]
    for pixels, thickness in zip(fingers, widths):
        for a, b in zip(pixels[:-1], pixels[1:]):
            cv2.line(mask, _pt(a), _pt(b), 255, thickness, cv2.LINE_AA)
        cv2.circle(mask, _pt(pixels[-1]), thickness // 2, 255, -1, cv2.LINE_AA)
    # shading: brighter towards the middle of every finger and the palm (distance to the silhouette edge)
    inside = cv2.distanceTransform((mask > 127).astype(np.uint8), cv2.DIST_L2, 5)
    shade = (0.62 + 0.38 * np.clip(inside / max(2.0, 0.05 * scale), 0.0, 1.0)) * light
    skin = np.asarray(skin_rgb, np.float32)
    colour = np.clip(skin[None, None, :] * shade[..., None], 0, 255).astype(np.uint8)
    crease = tuple(int(c) for c in np.clip(skin * 0.62 * light, 0, 255))
    nail = tuple(int(c) for c in np.clip((skin * 0.55 + 115) * light, 0, 255))
    for pixels, thickness in zip(fingers, widths):  # creases at the finger joints, a nail at the tip
        half = 0.45 * thickness
        for k in (1, 2):
            d = pixels[k + 1] - pixels[k - 1]
            normal = np.array([-d[1], d[0]]) / (np.linalg.norm(d) + 1e-9)
            cv2.line(colour, _pt(pixels[k] - half * normal), _pt(pixels[k] + half * normal), crease, 1, cv2.LINE_AA)
        along = (pixels[-1] - pixels[-2]) / (np.linalg.norm(pixels[-1] - pixels[-2]) + 1e-9)
        angle = float(np.degrees(np.arctan2(along[1], along[0])))
        axes = (max(1, int(0.36 * thickness)), max(1, int(0.28 * thickness)))
        cv2.ellipse(colour, _pt(pixels[-1] - 0.25 * thickness * along), axes, angle, 0, 360, nail, -1, cv2.LINE_AA)
    for x, y, *_ in _FINGERS[1:]:  # knuckle creases across the back of the hand
        a, b = pose.to_image(np.array([[x - 0.03, y + 0.05], [x + 0.03, y + 0.05]]))
        cv2.line(colour, _pt(a), _pt(b), crease, 1, cv2.LINE_AA)
    return colour, cv2.GaussianBlur(mask, (5, 5), 0).astype(np.float32) / 255.0


def landmark_points(pose: HandPose) -> np.ndarray:
    """Pixel positions of the drawn wrist and finger joints (21 x 2, MediaPipe's order: wrist, then thumb to
    little finger from base to tip): the ground truth a tracker's landmarks are compared with."""
    points = [np.zeros(2)] + [p for finger in _finger_joints(pose) for p in finger]
    return pose.to_image(np.array(points))
