"""What a plan is made of: the studies a report shows (:class:`Study`) and the rows of the thesis' tables it opens
with (:class:`Row`). Each chapter's plan is in :mod:`hrc_lab.report.plans`; ``hrc-lab-reproduce`` runs its studies
and ``hrc-lab-report`` builds its report from their runs, and nothing else: a result exists when it is a study of
its chapter's plan.

A study is one sweep, ``hrc-lab experiment=<experiment> <overrides> hydra/launcher=joblib`` (its Reproduce line).
Its runs are the finished runs of the experiment whose variant is the study's: the overrides beyond the experiment
file's own sweep keys, hashed as :func:`hrc_lab.run_naming.variant_of` hashes a job's. The experiment as configured
(no overrides) is the default study; a study with overrides asks a question (an ablation) or runs hrc_lab's ★
method where it is not one of the experiment's own sweep values.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from functools import cache

from omegaconf import OmegaConf

from hrc_lab.run_naming import CONF_DIR, variant_of

JOBLIB = "hydra/launcher=joblib"
MAX_TITLE = 100  # characters of a section title (a variant's overrides belong in its Reproduce line)


@cache
def experiment_file(experiment: str) -> dict:
    """``conf/experiment/<experiment>.yaml`` as a plain dict (not composed: its own keys only)."""
    path = CONF_DIR / "experiment" / f"{experiment}.yaml"
    if not path.is_file():
        raise ValueError(f"plan: no experiment file conf/experiment/{experiment}.yaml")
    return OmegaConf.to_container(OmegaConf.load(path), resolve=False)


def sweep_keys(experiment: str) -> list[str]:
    """The keys the experiment file sweeps (``hydra.sweeper.params``): its protocol, not a variant."""
    params = ((experiment_file(experiment).get("hydra") or {}).get("sweeper") or {}).get("params") or {}
    return list(params)


@dataclass(frozen=True)
class Study:
    """One sweep of a plan and the report section its runs make.

    ``key``: the section's anchor and file stem (the table tag for the default study). ``title``: an ablation's or a
    ★ study's heading (the default study's comes from its section builder). ``question``: what an ablation answers,
    printed under its heading; a default or ★ study has none. ``star``: the study runs hrc_lab's ★ method."""

    experiment: str
    overrides: tuple[str, ...] = ()
    key: str = ""
    title: str = ""
    question: str = ""
    star: bool = False
    launcher: str | None = JOBLIB  # None: a single run (an experiment file that sweeps nothing)
    # more sweeps whose runs join this section (experiment files logging to the same MLflow experiment), run after it
    also: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.key:
            object.__setattr__(self, "key", self.table if not self.overrides else "")
        if not re.fullmatch(r"[a-z0-9_]+", self.key or ""):
            raise ValueError(f"plan: study {self.command!r} needs a key of lower-case letters, digits and _")
        if self.overrides and not self.title:
            raise ValueError(f"plan: study {self.key!r} has overrides and needs a title of its own")
        if len(self.title) >= MAX_TITLE:
            raise ValueError(f"plan: study {self.key!r}'s title is {len(self.title)} characters (< {MAX_TITLE})")

    @property
    def table(self) -> str:
        """The section builder of its runs (the experiment file's ``table``, the runs' ``table`` tag)."""
        return str(experiment_file(self.experiment)["table"])

    @property
    def mlflow_experiment(self) -> str:
        """The MLflow experiment its runs log to (the experiment file's ``name``)."""
        return str(experiment_file(self.experiment)["name"])

    @property
    def default(self) -> bool:
        return not self.overrides

    @property
    def ablation(self) -> bool:
        return bool(self.overrides) and not self.star

    @property
    def argv(self) -> tuple[str, ...]:
        """``hrc-lab``'s arguments."""
        return (f"experiment={self.experiment}", *self.overrides, *([self.launcher] if self.launcher else []))

    @property
    def sweeps(self) -> list[tuple[str, ...]]:
        """``hrc-lab``'s arguments of each sweep the study runs: its own, then those of ``also``."""
        launcher = [self.launcher] if self.launcher else []
        return [self.argv, *((f"experiment={other}", *self.overrides, *launcher) for other in self.also)]

    @property
    def command(self) -> str:
        """The Reproduce line: the one command that computes the section."""
        return " && ".join(shlex.join(["hrc-lab", *argv]) for argv in self.sweeps)

    @property
    def variant(self) -> str:
        """The variant tag of the study's runs (``default`` for the experiment as configured)."""
        return variant_of(list(self.overrides), sweep_keys(self.experiment))[0]


@dataclass(frozen=True)
class Pick:
    """Where a report's opening table reads one of its numbers: the results of the study ``study`` (a key) for the
    row ``row`` of its section's ``results`` (a method, e.g. ``ours``)."""

    study: str
    row: str
    label: str = ""  # shown after "as written" / "★" (e.g. "300 cycles"); the method's label by default


@dataclass(frozen=True)
class Row:
    """One row of a thesis table or one stated number of a figure, as the report's opening table and the scoreboard
    (``reports/README.md``) show it: the thesis' value(s), the thesis' method as hrc_lab runs it, and hrc_lab's ★
    method where there is one.

    ``thesis``: the dotted path of the row in ``thesis_results.yaml`` (e.g. ``ch4.table_4_3.ours.sr``), read per
    column of ``columns`` (the table's own ``columns`` list when empty). A figure's qualitative statement is a
    ``claim`` instead (the thesis' words); the section's results then say in ``text`` what ours shows and in ``met``
    whether it agrees. ``why``: one short line on why ours differs,
    which may link an ablation of the plan as ``[text](#<study key>)``. ``higher``: whether more is better (a
    success rate) or less (steps, time); ``lower``: columns where less is better in a row whose others are higher
    (the steps beside a success rate); a row is within the thesis' spread when every column is, or above it."""

    table: str  # the thesis table or figure, e.g. "Table 4.3"
    name: str  # the thesis' row, e.g. "Ours (Algorithm 2)"
    thesis: str
    as_written: Pick | None
    claim: str = ""
    star: Pick | None = None
    columns: tuple[str, ...] = ()
    why: str = ""
    higher: bool = True
    lower: tuple[str, ...] = ()
    headline: bool = True  # a row of the scoreboard too (not only of the report's opening table)


@dataclass(frozen=True)
class Plan:
    """A report and the studies that make it, in the order its sections appear (each thesis table's default study,
    its ★ study, then the ablations). ``extra``: steps whose output the report links but no table reads (the
    rendered demonstration videos), as ``hrc-lab`` argument tuples. ``note``: what our world is, at most three
    lines."""

    topic: str
    title: str
    note: str
    studies: tuple[Study, ...]
    rows: tuple[Row, ...] = ()
    extra: tuple[tuple[str, ...], ...] = ()

    def study(self, key: str) -> Study:
        found = [study for study in self.studies if study.key == key]
        if not found:
            raise KeyError(f"plan {self.topic}: no study {key!r}")
        return found[0]

    def check(self) -> None:
        """Study keys are unique; each (experiment, variant) is one study's; every row reads studies of the plan."""
        keys = [study.key for study in self.studies]
        if len(keys) != len(set(keys)):
            raise ValueError(f"plan {self.topic}: a study key is used twice: {keys}")
        variants = [(study.mlflow_experiment, study.variant) for study in self.studies]
        if len(variants) != len(set(variants)):
            raise ValueError(f"plan {self.topic}: two studies select the same runs: {variants}")
        for row in self.rows:
            for pick in (row.as_written, row.star):
                if pick is not None:
                    self.study(pick.study)


def studies_of(plans, experiment: str) -> list[Study]:
    """Every study of ``plans`` that runs ``experiment``."""
    return [study for plan in plans for study in plan.studies if study.experiment == experiment]

