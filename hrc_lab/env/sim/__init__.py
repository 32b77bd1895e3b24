"""robosuite (UR5e on MuJoCo) environments of Ch.3 and Ch.4; importing this package registers them with robosuite.

The thesis used CoppeliaSim and a UR10 with a suction cup; here a UR5e with the suction cup of
:mod:`hrc_lab.env.sim.suction` stands at a table. ``robosuite.make("PackageToOrder", ...)`` and
``robosuite.make("ErrorCorrection", ...)`` work once this package is imported; :func:`make_env` builds either
from a validated ``env`` config node.
"""

import logging

# robosuite warns on import about optional extras (private macros, robosuite_models, mink) that we do not use.
logging.disable(logging.WARNING)
try:
    import robosuite  # noqa: F401
finally:
    logging.disable(logging.NOTSET)
logging.getLogger("robosuite_logs").setLevel(logging.WARNING)  # its INFO lines (controller files) are noise here

from hrc_lab.env.sim.error_correction import ErrorCorrection  # noqa: E402
from hrc_lab.env.sim.factory import make_env  # noqa: E402
from hrc_lab.env.sim.package_to_order import PackageToOrder  # noqa: E402

__all__ = ["ErrorCorrection", "PackageToOrder", "make_env"]
