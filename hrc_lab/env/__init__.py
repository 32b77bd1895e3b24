"""Environments and task specifications; ``conf/env/<file>.yaml`` selects one by ``name``.

One subpackage per world, each with its spec, simulator and data generation:

- :mod:`hrc_lab.env.robot`: the Ch.3/Ch.4 robot cells (package-to-order spec, config schemas, robosuite cells);
- :mod:`hrc_lab.env.assembly`: the Ch.5 assemble-to-order domain and its generated hand videos;
- :mod:`hrc_lab.env.clutter`: the Ch.6 clutter scenes and their labelling rule;
- :mod:`hrc_lab.env.fetch`: gymnasium-robotics' Fetch tasks, a public benchmark of the DRL agents (built by
  :mod:`hrc_lab.rl.benchmarks`).

The specs and config schemas imported here import no simulator; the robosuite cells
(:mod:`hrc_lab.env.robot.factory`, it registers ``PackageToOrder`` and ``ErrorCorrection`` with robosuite), the
clutter scenes (:mod:`hrc_lab.env.clutter.scenes`, pure MuJoCo) and the videos (:mod:`hrc_lab.env.assembly.video`,
OpenCV) are imported on demand.
"""

from hrc_lab.env.assembly.spec import AssembleToOrderSpec
from hrc_lab.env.clutter.spec import ClutterSpec, VmrdSpec
from hrc_lab.env.fetch import FetchSpec
from hrc_lab.env.robot.settings import (
    AssembleToOrderConfig,
    ErrorCorrectionConfig,
    PackageToOrderConfig,
    SimSettings,
)
from hrc_lab.env.robot.spec import PackageToOrderSpec
from hrc_lab.registry import Registry

ENVS = Registry("env")
# ENVS.build(cfg, seed=...) makes the robosuite cell of a robot env (the Ch.5 assembly spec's is the robot side of
# its HRC loop); the Ch.6 clutter scenes are a specification that their protocols' generators read (nothing to build).
ENVS.register("package_to_order", PackageToOrderConfig, "hrc_lab.env.robot.factory:make_env")
ENVS.register("error_correction", ErrorCorrectionConfig, "hrc_lab.env.robot.factory:make_env")
ENVS.register("assemble_to_order", AssembleToOrderConfig, "hrc_lab.env.robot.factory:make_env")
ENVS.register("clutter", ClutterSpec)
ENVS.register("vmrd", VmrdSpec)  # Table 6.3: a data set in VMRD v2's layout, or the clutter scenes written in it
ENVS.register("fetch", FetchSpec)  # rl/fetch: the Fetch task hrc_lab.rl.benchmarks makes (protocol rl_fetch)

__all__ = [
    "ENVS",
    "AssembleToOrderConfig",
    "AssembleToOrderSpec",
    "ClutterSpec",
    "ErrorCorrectionConfig",
    "FetchSpec",
    "PackageToOrderConfig",
    "PackageToOrderSpec",
    "SimSettings",
    "VmrdSpec",
]
