"""Hyper-parameter search with Hydra's Optuna sweeper (``hydra/sweeper=optuna``, docs/search.md; light: no torch,
mlflow or optuna import at module level).

A search space is a file ``conf/search/<name>.yaml`` selected with ``search=<name>``: it selects the Optuna sweeper,
names the metric a trial reports (``search.objective``, a key of the protocol's return dict) and replaces the
experiment file's grid (``hydra.sweeper.params``) with its dimensions, fixing the grid's keys (env, seed) to one value
each. :class:`StudyCallback` (``conf/hydra/default.yaml``) checks the space before the first trial, names the study
(the sweep folder's name unless ``hydra.sweeper.study_name`` is set), and at the end prints and logs the best trial.
Every trial is an MLflow run tagged ``study``, ``objective`` and ``search_keys`` (:func:`trial_tags`), of its own
variant (the sampled values are overrides), so no trial enters a report's default table.
"""

from __future__ import annotations

import sys

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf, read_write

from hrc_lab.config import ConfigError
from hrc_lab.run_naming import is_optuna, study_name

SEARCH_KEYS = ("name", "objective")  # the keys of the `search` node (conf/search/*.yaml)
_ABSENT = object()


DEFAULT_OBJECTIVE = "sr"  # the success rate most protocols return; a search file names another


def objective_of(cfg: DictConfig) -> str:
    """The metric a trial reports to Optuna: ``search.objective``, else ``sr``."""
    return (cfg.get("search") or {}).get("objective") or DEFAULT_OBJECTIVE


def trial_tags(cfg: DictConfig, hydra_cfg: DictConfig) -> dict[str, str]:
    """The tags of a trial's MLflow run (empty outside an Optuna sweep)."""
    if not is_optuna(hydra_cfg):
        return {}
    return {"study": study_name(hydra_cfg), "objective": str(objective_of(cfg)),
            "search": str((cfg.get("search") or {}).get("name", "none")),
            "search_keys": ",".join(str(k) for k in (hydra_cfg.sweeper.get("params") or {}))}


def check_search_space(config: DictConfig) -> None:
    """Raise :class:`ConfigError` naming the first bad entry of an Optuna sweep's config: a ``storage`` (optuna 2.10
    with SQLAlchemy 2 opens none), a key of ``hydra.sweeper.params`` that is neither in the composed config nor a
    config group (unless added with ``+``), a value the override grammar cannot parse, or an impossible range:
    ``interval(low, high)`` with low >= high, a ``log`` interval with low <= 0, an empty ``range(start, stop, step)``,
    a ``choice()`` of nothing."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import ChoiceSweep, IntervalSweep, RangeSweep
    from hydra.errors import HydraException

    if config.hydra.sweeper.get("storage"):
        raise ConfigError("hydra.sweeper.storage: optuna 2.10.1 (what hydra-optuna-sweeper 1.3.0 accepts) cannot open "
                          "a database beside mlflow's SQLAlchemy 2; leave it null (the trials are MLflow runs tagged "
                          "with the study, hrc_lab.report.search.study_trials)")
    choices = config.hydra.runtime.get("choices") or {}
    parser = OverridesParser.create()
    # the search file's dimensions, then the command line's sweeps (`'rl.tau=interval(0.01,0.1)'`: Hydra composes a
    # multirun without them and would only fail in the first trial)
    entries = [(f"{key}={value}", f"hydra.sweeper.params.{key}") for key, value in
               (config.hydra.sweeper.get("params") or {}).items()]
    entries += [(str(item), "") for item in config.hydra.overrides.task]
    for text, where in entries:
        try:
            override = parser.parse_override(text)
        except HydraException as err:
            raise ConfigError(f"{where or text}: cannot parse: {err}") from None
        key = override.get_key_element()
        where = where or f"{key} (command line)"
        if not where.startswith("hydra.") and not override.is_sweep_override():
            continue  # a plain command-line value: Hydra composed it already
        name = key.lstrip("+~")
        known = name in choices or OmegaConf.select(config, name, default=_ABSENT) is not _ABSENT
        if not key.startswith("+") and not known:
            raise ConfigError(f"{where}: unknown search-space key (not in the composed config of experiment "
                              f"{config.get('name')}, nor a config group)")
        if not override.is_sweep_override():
            continue
        sweep = override.value()
        bad = None
        if isinstance(sweep, IntervalSweep):
            if sweep.start >= sweep.end:
                bad = f"interval low {sweep.start} >= high {sweep.end}"
            elif "log" in sweep.tags and sweep.start <= 0:
                bad = f"log interval needs low > 0, got {sweep.start}"
        elif isinstance(sweep, RangeSweep):
            step = sweep.step if sweep.step is not None else 1
            if step == 0 or (sweep.stop - sweep.start) / step <= 0:
                bad = f"range({sweep.start}, {sweep.stop}, {step}) is empty"
        elif isinstance(sweep, ChoiceSweep) and not sweep.list:
            bad = "choice() has no options"
        if bad:
            raise ConfigError(f"{where}: impossible range: {bad}")


def maximizes_by_default(config: DictConfig) -> bool:
    """Whether a study optimises the default objective (no search file, ``sr``: a success rate) with no direction
    given on the command line: Optuna's default direction, minimize, would look for the worst settings."""
    given = any(str(item).startswith("hydra.sweeper.direction=") for item in config.hydra.overrides.hydra)
    search_file = (config.get("search") or {}).get("name", "none") != "none"
    return not given and not search_file and objective_of(config) == DEFAULT_OBJECTIVE


class StudyCallback(Callback):
    """Hydra callback of every sweep; acts under the Optuna sweeper only (module docstring)."""

    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        if not is_optuna(config.hydra):
            return
        try:
            check_search_space(config)
        except ConfigError as err:
            print(f"hrc-lab: config error: {err}", file=sys.stderr)
            sys.exit(2)
        # Called before Hydra instantiates the sweeper from this config: the study gets the name its trials are
        # tagged with (each job computes the same from its own config, study_name()).
        with read_write(config.hydra):
            config.hydra.sweeper.study_name = study_name(config.hydra)
            if maximizes_by_default(config):
                config.hydra.sweeper.direction = "maximize"

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        if not is_optuna(config.hydra):
            return
        from hrc_lab.report.search import report_study

        report_study(config, study_name(config.hydra), objective_of(config))
