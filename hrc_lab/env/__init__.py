"""Environments and task specifications; ``conf/env/<file>.yaml`` selects one by ``name``."""

from hrc_lab.env.assemble_to_order import AssembleToOrderSpec
from hrc_lab.env.package_to_order import PackageToOrderSpec
from hrc_lab.registry import Registry

ENVS = Registry("env")
ENVS.register("package_to_order", PackageToOrderSpec, "hrc_lab.env.package_to_order:PackageToOrderSpec")
ENVS.register("assemble_to_order", AssembleToOrderSpec, "hrc_lab.env.assemble_to_order:AssembleToOrderSpec")

__all__ = ["ENVS", "AssembleToOrderSpec", "PackageToOrderSpec"]
