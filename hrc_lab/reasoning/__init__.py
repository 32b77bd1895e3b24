"""Ch.4 reasoning module and its baselines, Ch.5 semantic planner; ``conf/reasoning/<name>.yaml`` selects one by
``name`` and ``REASONERS.build(cfg, spec=..., seed=...)`` makes it. Each method is registered once with its
family and display name (:mod:`hrc_lab.reasoning.configs`), which protocols and reports read."""

from hrc_lab.reasoning.configs import REASONERS

__all__ = ["REASONERS"]
