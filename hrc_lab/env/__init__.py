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
# ENVS.build(cfg, seed=...) makes the robosuite cell of a robot env; the Ch.5 assembly domain and the Ch.6 clutter
# scenes are specifications that their protocols' generators read (nothing to build).
ENVS.register("package_to_order", PackageToOrderConfig, "hrc_lab.env.sim.factory:make_env")
ENVS.register("error_correction", ErrorCorrectionConfig, "hrc_lab.env.sim.factory:make_env")
ENVS.register("assemble_to_order", AssembleToOrderSpec)
ENVS.register("clutter", ClutterSpec)

__all__ = [
    "ENVS",
    "AssembleToOrderSpec",
    "ClutterSpec",
    "ErrorCorrectionConfig",
    "PackageToOrderConfig",
    "PackageToOrderSpec",
    "SimSettings",
]
