"""Environments and task specifications; ``conf/env/<file>.yaml`` selects one by ``name``.

The task specs and config schemas here import no simulator; the robosuite cells live in :mod:`hrc_lab.env.sim`
(imported on demand, it registers ``PackageToOrder`` and ``ErrorCorrection`` with robosuite), the Ch.6 clutter
scenes in :mod:`hrc_lab.env.clutter_scene` (pure MuJoCo, imported on demand).
"""

from hrc_lab.env.assemble_to_order import AssembleToOrderSpec
from hrc_lab.env.clutter import ClutterSpec
from hrc_lab.env.package_to_order import PackageToOrderSpec
from hrc_lab.env.settings import ErrorCorrectionConfig, PackageToOrderConfig, SimSettings
from hrc_lab.registry import Registry

ENVS = Registry("env")
ENVS.register("package_to_order", PackageToOrderConfig, "hrc_lab.env.sim.package_to_order:PackageToOrder")
ENVS.register("error_correction", ErrorCorrectionConfig, "hrc_lab.env.sim.error_correction:ErrorCorrection")
ENVS.register("assemble_to_order", AssembleToOrderSpec, "hrc_lab.env.assemble_to_order:AssembleToOrderSpec")
ENVS.register("clutter", ClutterSpec, "hrc_lab.env.clutter:ClutterSpec")

__all__ = [
    "ENVS",
    "AssembleToOrderSpec",
    "ClutterSpec",
    "ErrorCorrectionConfig",
    "PackageToOrderConfig",
    "PackageToOrderSpec",
    "SimSettings",
]
