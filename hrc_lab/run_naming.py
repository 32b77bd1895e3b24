"""How a job's MLflow run is named and tagged (light: imports no MLflow; :mod:`hrc_lab.tracking` logs the run
under these names and tags, the reports read them back).

A run is named ``<experiment>-<method>-<scenario>-seed<k>`` (:func:`run_name`), followed by ``-v<hash>`` when the
job changes anything beyond the experiment file's own sweep keys or composes a config file that is not the
repository's (:func:`variant_of`, :func:`own_configs`): an ablation or a user's own config is never mistaken for
the default protocol. :func:`job_tags` gives the running Hydra job's sweep, overrides and variant."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

CONF_DIR = Path(__file__).resolve().parents[1] / "conf"  # the repository's config folder (an editable install's)


def method_of(cfg: DictConfig) -> str:
    """The method a run compares: the first of its tamp system, rl, perception, reasoning, motion and grasp modules
    that is not "none" (a Table 4.3 run is named after its system, which composes the others; a Ch.5 run with a
    trained action detector after the detector, not the planner it feeds; a guided RL run after its agent, not
    the planner that guides it)."""
    for group in ("tamp", "rl", "perception", "reasoning", "motion", "grasp"):
        node = cfg.get(group) or {}
        name = node.get("name", "none")
        if name != "none":
            # a guided agent is also named by its guidance ratio: Fig. 3.13 compares lambda 0, 0.7 and 1
            return f"{name}_lam{node.lam:g}" if group == "rl" and node.get("guidance", "none") != "none" else name
    return "none"


# Overrides that do not change what a job computes: where it logs and writes, its threads, how it resumes.
NEUTRAL_KEYS = ("experiment", "resume_from", "logger", "paths", "num_threads")


def variant_of(overrides: list[str], sweep_keys: list[str], own_configs: Sequence[str] = ()) -> tuple[str, list[str]]:
    """``("default", [])`` when the task ``overrides`` only set the experiment file's sweep keys (and neutral
    ones) and no ``own_configs`` were composed; otherwise ``("v<8 hex>", the extra overrides)``, the hash naming that
    set of changes and the user's config files (``<config path>.yaml@<content hash>``, from :func:`own_configs`)."""
    extra = []
    for override in overrides:
        key = override.lstrip("+~").split("=", 1)[0]
        if key in sweep_keys or key.split(".")[0] in NEUTRAL_KEYS:
            continue
        extra.append(override)
    if not extra and not own_configs:
        return "default", []
    extra = sorted(extra)
    return "v" + hashlib.sha1(" ".join(extra + sorted(own_configs)).encode()).hexdigest()[:8], extra


# Where the repository's config files come from: its conf/ folder, Hydra's own package, and Hydra's ConfigStore
# (hrc_lab's schemas, installed Hydra plugins' launchers and sweepers).
REPOSITORY_SOURCES = (f"file://{CONF_DIR}", "pkg://hydra.conf", "structured://")
# How a user adds a config source, by its Hydra provider ("main" is not the repository's after `--config-path`)
SOURCE_FLAGS = {"command-line": "--config-dir", "main": "--config-path",
                "hydra.searchpath in command-line": "hydra.searchpath", "hydra.searchpath in main": "hydra.searchpath"}


def own_configs(hydra_cfg: DictConfig) -> dict[str, list[str]]:
    """The config files a Hydra job composed that are not the repository's, by the source Hydra found them in, e.g.
    ``{"--config-dir /abs/dir": ["env/my_cell.yaml@<8 hex of its content>"]}``: empty when every source on the search
    path (``hydra.runtime.config_sources``) is the repository's. A file in a user's folder counts only if Hydra took it
    from there (the repository's conf/ comes first on the search path), and only if it can change what the job
    computes: files of the ``hydra`` node (launcher, sweeper, logging) and of the neutral groups are left out."""
    sources = hydra_cfg.runtime.get("config_sources") or []
    if all(f"{source.schema}://{source.path}" in REPOSITORY_SOURCES for source in sources):
        return {}
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra._internal.config_search_path_impl import ConfigSearchPathImpl
    from hydra.core.plugins import Plugins
    from omegaconf import OmegaConf

    Plugins.instance()  # registers Hydra's config source types (file://, pkg://, structured://)
    search_path = ConfigSearchPathImpl()
    for source in sources:
        search_path.append(source.provider, f"{source.schema}://{source.path}")
    # the job's defaults list again (every file composed, nested ones too), each looked up as Hydra did
    loader = ConfigLoaderImpl(config_search_path=search_path)
    overrides = [*hydra_cfg.overrides.hydra, *hydra_cfg.overrides.task]
    defaults = loader.compute_defaults_list(hydra_cfg.job.config_name, overrides, RunMode.RUN).defaults
    found: dict[str, list[str]] = {}
    for default in defaults:
        package = (default.package or "").split(".")[0]
        if default.config_path is None or package == "hydra" or package in NEUTRAL_KEYS:
            continue
        result = loader.repository.load_config(default.config_path)
        if result is None or result.path in REPOSITORY_SOURCES:
            continue
        content = f"{result.header}\n{result.defaults_list!r}\n{OmegaConf.to_yaml(result.config)}"
        item = f"{default.config_path}.yaml@{hashlib.sha1(content.encode()).hexdigest()[:8]}"
        where = found.setdefault(f"{SOURCE_FLAGS.get(result.provider, result.provider)} "
                                 f"{result.path.removeprefix('file://')}", [])
        if item not in where:
            where.append(item)
    return found


def run_name(cfg: DictConfig, scenario: str, variant: str = "default") -> str:
    name = f"{cfg.name}-{method_of(cfg)}-{scenario}-seed{cfg.seed}"
    return name if variant == "default" else f"{name}-{variant}"


OPTUNA = "optuna"  # hydra/sweeper=optuna (hrc_lab.search)


def is_optuna(hydra_cfg: DictConfig) -> bool:
    """Whether the job or sweep runs under the Optuna sweeper (``hydra/sweeper=optuna``, a multirun)."""
    multirun = hydra_cfg.get("mode") in (RunMode.MULTIRUN, "MULTIRUN")
    return multirun and (hydra_cfg.runtime.get("choices") or {}).get("hydra/sweeper") == OPTUNA


def study_name(hydra_cfg: DictConfig) -> str:
    """``hydra.sweeper.study_name``, else the sweep folder's name (what :class:`hrc_lab.search.StudyCallback` gives
    the sweeper): the ``study`` tag of an Optuna sweep's runs."""
    return str(hydra_cfg.sweeper.get("study_name") or Path(hydra_cfg.sweep.dir).name)


def sweep_id() -> str:
    """The sweep a job belongs to (its sweep folder relative to runs/), or "none" for a single run."""
    hydra_cfg = HydraConfig.get()
    if hydra_cfg.mode != RunMode.MULTIRUN:
        return "none"
    return Path(hydra_cfg.sweep.dir).name


def job_tags() -> dict[str, str]:
    """The sweep, the task overrides and the variant of the running Hydra job (``variant_overrides``: the extra
    overrides, then each user config source with the files taken from it, e.g. ``--config-dir /abs/dir
    (env/my_cell.yaml@1a2b3c4d)``)."""
    hydra_cfg = HydraConfig.get()
    overrides = list(hydra_cfg.overrides.task)
    # A grid sweep's keys are the experiment's protocol; an Optuna trial's sampled and fixed values are a variant of
    # its own (the search's keys are hydra.sweeper.params too), so no trial enters a report's default table.
    sweep_keys = [] if is_optuna(hydra_cfg) else list((hydra_cfg.sweeper.get("params") or {}).keys())
    own = own_configs(hydra_cfg)
    variant, extra = variant_of(overrides, sweep_keys, [item for items in own.values() for item in items])
    shown = extra + [f"{where} ({', '.join(items)})" for where, items in own.items()]
    return {
        "sweep": sweep_id(),
        "overrides": " ".join(overrides)[:5000],
        "variant": variant,
        "variant_overrides": " ".join(shown)[:5000],
    }
