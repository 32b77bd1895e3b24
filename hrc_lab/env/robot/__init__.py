"""The robot cells of Ch.3 and Ch.4 (thesis 3.3 and 4.3): a UR5e with a suction cup at a table, on robosuite/MuJoCo.

The thesis used CoppeliaSim and a UR10 with a suction cup; here a UR5e with the suction cup of
:mod:`~hrc_lab.env.robot.suction` stands at a table.

- :mod:`~hrc_lab.env.robot.spec`: the package-to-order task spec and episode sampler (4.3, Fig. 4.5-4.6), no
  simulator: the reasoning experiments of Ch.4 use it alone;
- :mod:`~hrc_lab.env.robot.settings`: the config schemas of ``conf/env/package_to_order*.yaml`` and
  ``conf/env/error_correction*.yaml`` (no simulator);
- :mod:`~hrc_lab.env.robot.cell`: the cell both environments share (action, physics, collisions, reward);
- :mod:`~hrc_lab.env.robot.package_cell` (``PackageToOrder``, Ch.4) and
  :mod:`~hrc_lab.env.robot.correction_cell` (``ErrorCorrection``, Ch.3): the environments; importing either
  module registers its class with robosuite, so ``robosuite.make("PackageToOrder", ...)`` works afterwards;
- :mod:`~hrc_lab.env.robot.factory`: :func:`make_env` builds either from a validated ``env`` config
  (``ENVS.build``; importing it registers both);
- :mod:`~hrc_lab.env.robot.expert`: the scripted expert that records the demonstrations (4.3).

This package imports nothing itself, so the specs and schemas stay light; robosuite is imported (quietly) by
:mod:`~hrc_lab.env.robot.cell`.
"""
