"""Suction end effector (thesis 3.3: "a UR10 robot arm with a suction cup").

robosuite ships no suction gripper, so :class:`SuctionCup` is a gripper model without actuated joints and
:class:`Suction` implements the binary suction action: switching it on welds the object touching the cup's lip to
the cup with a MuJoCo weld equality (declared inactive in the model, one per object, and activated at the object's
current relative pose so nothing jumps); switching it off deactivates the weld and the object falls free.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
from robosuite.models.grippers import register_gripper
from robosuite.models.grippers.gripper_model import GripperModel

ASSET = Path(__file__).parent / "assets" / "suction_cup.xml"


@register_gripper
class SuctionCup(GripperModel):
    """A cup on a short stem; tool axis +z, lip (``grip_site``) 0.075 m from the flange."""

    def __init__(self, idn=0):
        super().__init__(str(ASSET), idn=idn)

    def format_action(self, action):
        return action

    @property
    def init_qpos(self):
        return None

    @property
    def _important_geoms(self):
        return {"left_finger": [], "right_finger": [], "left_fingerpad": [], "right_fingerpad": []}


def weld_elements(cup_body: str, object_bodies: list[str]) -> list[ET.Element]:
    """One inactive weld per object, to be appended to the model's <equality> section."""
    return [
        ET.Element("weld", name=f"suction_{body}", body1=cup_body, body2=body, active="false")
        for body in object_bodies
    ]


class Suction:
    """Attach/release objects by toggling their weld to the cup.

    An object can be attached when the lip (``grip_site``) is within ``reach`` of the object's top face and inside
    its footprint (the bellows give 1.5 cm of compliance): the cup has to touch the part, as a real one does.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, cup_body: str, grip_site: str,
                 object_bodies: list[str], half_sizes: np.ndarray, reach: float = 0.015) -> None:
        self.model, self.data = model, data
        self.cup = model.body(cup_body).id
        self.site = model.site(grip_site).id
        self.bodies = [model.body(b).id for b in object_bodies]
        self.welds = [model.equality(f"suction_{b}").id for b in object_bodies]
        self.half_sizes = np.asarray(half_sizes, dtype=float)
        self.reach = reach
        self.held = -1
        self.enabled = True

    def reset(self) -> None:
        self.data.eq_active[self.welds] = 0
        self.held = -1
        self.enabled = True

    def touching(self) -> int:
        """Index of the object whose top face the lip touches, or -1."""
        lip = self.data.site_xpos[self.site]
        for i, body in enumerate(self.bodies):
            centre = self.data.xpos[body]
            half = self.half_sizes[i]
            top = centre[2] + half[2]
            inside = np.all(np.abs(lip[:2] - centre[:2]) <= half[:2])
            if inside and -0.005 <= lip[2] - top <= self.reach:
                return i
        return -1

    def command(self, on: bool) -> None:
        """Apply the binary suction action."""
        if on and self.enabled and self.held < 0:
            target = self.touching()
            if target >= 0:
                self.attach(target)
        elif not on and self.held >= 0:
            self.release()

    def attach(self, index: int) -> None:
        """Weld object ``index`` to the cup at its current pose relative to the cup."""
        body, weld = self.bodies[index], self.welds[index]
        p1, p2 = self.data.xpos[self.cup], self.data.xpos[body]
        q1, q2 = self.data.xquat[self.cup], self.data.xquat[body]
        rel_pos = self.data.xmat[self.cup].reshape(3, 3).T @ (p2 - p1)
        q1_inv = np.empty(4)
        mujoco.mju_negQuat(q1_inv, q1)
        rel_quat = np.empty(4)
        mujoco.mju_mulQuat(rel_quat, q1_inv, q2)
        eq = self.model.eq_data[weld]
        eq[0:3] = 0.0  # anchor on body2
        eq[3:6] = rel_pos
        eq[6:10] = rel_quat
        eq[10] = 1.0  # torque scale
        self.data.eq_active[weld] = 1
        self.held = index

    def release(self) -> None:
        if self.held >= 0:
            self.data.eq_active[self.welds[self.held]] = 0
            self.held = -1

    def disable(self) -> None:
        """Switch the effector off for good (DRL setting of 3.3: after a collision)."""
        self.release()
        self.enabled = False
