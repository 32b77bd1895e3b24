"""Experiment protocols: what one Hydra job of a thesis table or figure does, one module per chapter
(``ch3_motion``, ``ch4_reasoning``, ``ch4_motion``, ``ch5_planner``, ``ch5_perception``, ``ch6_grasp``, ``collect``),
plus ``rl_benchmarks`` (the DRL agent on public Fetch tasks).
:mod:`hrc_lab.experiments.schemas` holds their config schemas and the ``PROTOCOLS`` registry (``protocol.name``
-> schema, protocol function), light enough to validate a config without importing torch."""

from hrc_lab.experiments.schemas import PROTOCOLS

__all__ = ["PROTOCOLS"]
