"""Build a robosuite cell from a validated ``env`` config (:mod:`hrc_lab.env.robot.settings`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from hrc_lab.env.robot.assembly_cell import AssemblyCell
from hrc_lab.env.robot.cell import HRCCell
from hrc_lab.env.robot.correction_cell import ErrorCorrection
from hrc_lab.env.robot.package_cell import PackageToOrder
from hrc_lab.env.robot.settings import (
    AssembleToOrderConfig,
    ErrorCorrectionConfig,
    PackageToOrderConfig,
    SimSettings,
)
from hrc_lab.env.robot.spec import PackageToOrderSpec


def cell_kwargs(sim: SimSettings) -> dict:
    return {
        "control_freq": sim.control_freq,
        "physics_timestep": sim.physics_timestep,
        "horizon": sim.horizon,
        "success_threshold": sim.success_threshold,
        "max_joint_step": np.deg2rad(sim.max_joint_step_deg),
        "yaw_action": sim.yaw_action,
        "disable_effector_on_collision": sim.disable_effector_on_collision,
        "grip_after_step": sim.grip_after_step,
        "lean_step": sim.lean_step,
    }


def make_env(cfg: PackageToOrderConfig | ErrorCorrectionConfig | AssembleToOrderConfig, seed: int | None = None,
             **render) -> HRCCell:
    """The cell an ``env`` config describes (``ENVS.build(cfg, seed=...)``); ``render`` takes robosuite's
    off-screen camera arguments."""
    kwargs = {**cell_kwargs(cfg.sim), "seed": seed, **render}
    if isinstance(cfg, PackageToOrderConfig):
        fields = {f.name for f in dataclasses.fields(PackageToOrderSpec)}
        spec = PackageToOrderSpec(**{k: getattr(cfg, k) for k in fields})
        return PackageToOrder(spec, case=cfg.sim.case, n_missing=cfg.sim.n_missing, **kwargs)
    if isinstance(cfg, ErrorCorrectionConfig):
        return ErrorCorrection(task=cfg.task, case=cfg.sim.case, **kwargs)
    if isinstance(cfg, AssembleToOrderConfig):
        return AssemblyCell(cfg, **kwargs)
    raise TypeError(f"env '{type(cfg).__name__}' has no robot cell; use package_to_order, error_correction or "
                    "assemble_to_order")
