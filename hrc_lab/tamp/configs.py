"""The ``tamp`` config schema (light: no torch import) and its registry: which system of Table 4.3 a run is.

A ``conf/tamp/<name>.yaml`` is a preset: its defaults list sets the reasoning, motion and rl groups the system is
made of, and command-line group choices still win (``tamp=ours reasoning=gnn`` runs Algorithm 2 with the GNN
baseline as the reasoning module). The protocol checks that the groups make the named system
(:class:`hrc_lab.experiments.schemas.Table43Protocol`). ``TAMPS.build(cfg)`` makes the system
(:mod:`hrc_lab.tamp.systems`), which trains its modules and runs the protocol's trials and videos.
"""

from __future__ import annotations

from dataclasses import dataclass

from hrc_lab.registry import Registry

TAMPS = Registry("tamp")


@dataclass
class TampConfig:
    """A system of Table 4.3; nothing to set beyond its ``name`` (its modules are the other groups)."""


# Table 4.3's rows, in its order: name -> (system class in hrc_lab.tamp.systems, the reports' label). Ours:
# reasoning module + two-level motion module (Algorithm 2); ours_hrc (not in the thesis): the same with hrc_lab's
# reasoning module (reasoning=hrc); DRL: one flat DDPG + HER agent, no reasoning module;
# RM+RRT-Connect: the same reasoning module, the motion module replaced by OMPL's RRT-Connect ([138], [139]).
SYSTEMS = {"ours": ("OursSystem", "Ours (Algorithm 2)"),
           "ours_hrc": ("OursSystem", "★ Ours with hrc_lab's reasoning module (beyond the thesis)"),
           "drl": ("DRLSystem", "DRL (DDPG + HER)"),
           "rm_rrt_connect": ("RMRRTConnectSystem", "RM+RRT-Connect")}
LABELS = {name: label for name, (_, label) in SYSTEMS.items()}
for _name, (_system, _) in SYSTEMS.items():
    TAMPS.register(_name, TampConfig, f"hrc_lab.tamp.systems:{_system}")
