"""Experiment protocols, one per thesis table or figure; see :mod:`hrc_lab.experiments.protocols`."""

from hrc_lab.experiments.protocols import PROTOCOLS

__all__ = ["PROTOCOLS"]
