"""Build a robosuite cell from a validated ``env`` config (:mod:`hrc_lab.env.settings`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from hrc_lab.env.package_to_order import PackageToOrderSpec
from hrc_lab.env.settings import ErrorCorrectionConfig, PackageToOrderConfig, SimSettings
from hrc_lab.env.sim.cell import HRCCell
from hrc_lab.env.sim.error_correction import ErrorCorrection
from hrc_lab.env.sim.package_to_order import PackageToOrder


def cell_kwargs(sim: SimSettings) -> dict:
    return {
        "control_freq": sim.control_freq,
        "physics_timestep": sim.physics_timestep,
        "horizon": sim.horizon,
        "success_threshold": sim.success_threshold,
        "max_joint_step": np.deg2rad(sim.max_joint_step_deg),
        "yaw_action": sim.yaw_action,
        "disable_effector_on_collision": sim.disable_effector_on_collision,
    }


def make_env(config: PackageToOrderConfig | ErrorCorrectionConfig, seed: int | None = None, **render) -> HRCCell:
    """The cell an ``env`` config describes; ``render`` takes robosuite's off-screen camera arguments."""
    kwargs = {**cell_kwargs(config.sim), "seed": seed, **render}
    if isinstance(config, PackageToOrderConfig):
        fields = {f.name for f in dataclasses.fields(PackageToOrderSpec)}
        spec = PackageToOrderSpec(**{k: getattr(config, k) for k in fields})
        return PackageToOrder(spec, case=config.sim.case, n_missing=config.sim.n_missing, **kwargs)
    if isinstance(config, ErrorCorrectionConfig):
        return ErrorCorrection(task=config.task, case=config.sim.case, **kwargs)
    raise TypeError(f"env '{type(config).__name__}' has no robot cell; use package_to_order or error_correction")
