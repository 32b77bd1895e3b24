"""Shared fixtures: compose the real configs (shrinking sizes, not behaviour) and keep every output in tmp_path."""

from __future__ import annotations

import copy
import logging
import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import OmegaConf, open_dict

# Off-screen MuJoCo rendering (the Ch.6 clutter scenes) must be chosen before the first `import mujoco`, which an
# earlier test may do through robosuite.
os.environ.setdefault("MUJOCO_GL", "egl")

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"


@pytest.fixture(scope="session", autouse=True)
def migrated_sqlite_template(tmp_path_factory):
    """Every sqlite MLflow store a test opens in this process starts as a copy of one empty, migrated store instead
    of running MLflow's schema migrations again (3-5 s per store on 2 cores, about a third of the suite's time when
    each test made its own). The stores are the same: the copy is what the migrations write. Returns the template's
    path, to copy where a test's subprocess will open a store (tests/test_sweeps.py)."""
    import mlflow.store.db.utils as db_utils
    import mlflow.store.model_registry.sqlalchemy_store as registry_store
    from mlflow.tracking import MlflowClient

    template = tmp_path_factory.mktemp("mlflow_template") / "mlflow.db"
    MlflowClient(f"sqlite:///{template}").search_experiments()
    migrate = db_utils._initialize_tables

    def initialize(engine) -> None:
        path = engine.url.database if engine.url.get_backend_name() == "sqlite" else None
        if not path or path == ":memory:":
            return migrate(engine)
        engine.dispose()  # the pool's connections hold the empty file open
        shutil.copyfile(template, path)

    patch = pytest.MonkeyPatch()
    patch.setattr(db_utils, "_initialize_tables", initialize)
    patch.setattr(registry_store, "_initialize_tables", initialize)
    yield template
    patch.undo()


@pytest.fixture
def compose_config(tmp_path, monkeypatch):
    """compose_config(*overrides, return_hydra_config=False) -> the composed DictConfig, with runs/ redirected to
    tmp_path."""
    monkeypatch.setenv("HRC_LAB_RUNS", str(tmp_path / "runs"))

    def _compose(*overrides: str, return_hydra_config: bool = False):
        GlobalHydra.instance().clear()
        with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
            return compose("config", overrides=list(overrides), return_hydra_config=return_hydra_config)

    yield _compose
    GlobalHydra.instance().clear()


@dataclass
class Job:
    """What one in-process ``hrc-lab`` job left behind."""

    metrics: dict[str, float]  # what hrc_lab.cli.run returned
    tracking_uri: str  # the job's MLflow store, a sqlite file under runs_dir
    client: Any  # an MlflowClient on that store
    run: Any  # the job's MLflow run (mlflow.entities.Run)
    runs_dir: Path  # paths.runs_dir (tmp_path / "runs")
    output_dir: Path  # the Hydra job's output folder (hydra.runtime.output_dir)
    log: str  # what the job logged on the "hrc_lab" logger (its "<run name>: sr=..., ..." line)


def _prepare_hydra_job(cfg) -> Path:
    """Fill in what Hydra's launcher sets for a job (mode, job number, output folder), write the ``.hydra`` folder
    as Hydra does, and make ``cfg`` the current HydraConfig. Returns the output folder."""
    hydra_cfg = cfg.hydra
    with open_dict(hydra_cfg):
        if hydra_cfg.mode == RunMode.MULTIRUN:  # job 0 of a sweep
            hydra_cfg.sweep.dir = str(hydra_cfg.sweep.dir)  # resolve ${now:...} once
            hydra_cfg.job.num = 0
            hydra_cfg.job.id = "0"
            output_dir = Path(hydra_cfg.sweep.dir) / str(hydra_cfg.sweep.subdir)
        else:
            hydra_cfg.mode = RunMode.RUN
            hydra_cfg.run.dir = str(hydra_cfg.run.dir)
            output_dir = Path(hydra_cfg.run.dir)
        hydra_cfg.runtime.output_dir = str(output_dir.resolve())
    HydraConfig().set_config(cfg)
    hydra_dir = output_dir / str(hydra_cfg.output_subdir)
    hydra_dir.mkdir(parents=True, exist_ok=True)
    OmegaConf.save(_task_config(cfg), hydra_dir / "config.yaml")
    OmegaConf.save(OmegaConf.create({"hydra": hydra_cfg}), hydra_dir / "hydra.yaml")
    OmegaConf.save(hydra_cfg.overrides.task, hydra_dir / "overrides.yaml")
    return output_dir


def _task_config(cfg):
    """The config a Hydra task function receives: everything but the ``hydra`` node."""
    task_cfg = copy.deepcopy(cfg)
    with open_dict(task_cfg):
        del task_cfg["hydra"]
    return task_cfg


@pytest.fixture
def run_job(tmp_path, compose_config, caplog):
    """run_job(*overrides) -> Job: one ``hrc-lab <overrides>`` job in this process, as lightning-hydra-template's
    tests run train(cfg): compose with the hydra node, set HydraConfig as Hydra's launcher does, call
    ``hrc_lab.cli.run`` (in the main thread: it installs signal handlers). Every output (runs dir, MLflow sqlite
    store, Hydra output folder) is under tmp_path. A config error propagates as hrc_lab.registry.ConfigError (the
    console script turns it into exit code 2). Global state run() changes (torch threads, deterministic mode,
    seed environment variables) is restored afterwards so later tests do not inherit it."""
    import torch
    from mlflow.tracking import MlflowClient

    from hrc_lab.cli import run

    runs_dir = tmp_path / "runs"
    tracking_uri = f"sqlite:///{runs_dir / 'mlflow.db'}"
    environ = dict(os.environ)
    threads = torch.get_num_threads()
    deterministic = torch.are_deterministic_algorithms_enabled()
    caplog.set_level(logging.INFO, logger="hrc_lab")

    def _run(*overrides: str) -> Job:
        cfg = compose_config(*overrides, return_hydra_config=True)
        cfg.paths.runs_dir = str(runs_dir)
        cfg.logger.tracking_uri = tracking_uri
        output_dir = _prepare_hydra_job(cfg)
        first_record = len(caplog.records)
        metrics = run(_task_config(cfg))
        log = "\n".join(r.getMessage() for r in caplog.records[first_record:] if r.name.startswith("hrc_lab"))
        client = MlflowClient(tracking_uri)
        experiment = client.get_experiment_by_name(cfg.name)
        (latest,) = client.search_runs([experiment.experiment_id], order_by=["attributes.start_time DESC"],
                                       max_results=1)
        return Job(metrics, tracking_uri, client, latest, runs_dir, output_dir, log)

    yield _run
    HydraConfig.instance().cfg = None
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(deterministic)
    for key in set(os.environ) - set(environ):
        del os.environ[key]
    os.environ.update(environ)


@pytest.fixture(scope="session")
def base_run_name():
    """base_run_name(run) -> an MLflow run's name without the ``-<variant>`` suffix hrc-lab appends when a job's
    overrides go beyond its experiment's sweep keys (tag ``variant``), as the tests' size-shrinking overrides do."""

    def _base(run) -> str:
        name, variant = run.info.run_name, run.data.tags.get("variant", "default")
        if variant == "default":
            return name
        assert name.endswith(f"-{variant}"), (name, variant)
        return name.removesuffix(f"-{variant}")

    return _base


@pytest.fixture
def cli_env(tmp_path):
    """Environment for running the console scripts with all outputs under tmp_path."""
    env = dict(os.environ, HRC_LAB_RUNS=str(tmp_path / "runs"), PYTHONWARNINGS="ignore")
    return env


@pytest.fixture(scope="session")
def console_script():
    """console_script(name) -> path of an installed console script (hrc-lab, hrc-lab-report) beside the running
    interpreter, so the tests work without an activated venv."""
    return lambda name: str(Path(sys.executable).with_name(name))


@pytest.fixture
def job_report(tmp_path):
    """job_report(job, topic, **plan_changes) -> str: :func:`report_of` into ``tmp_path / "report"``."""
    return lambda job, topic, **changes: report_of(job, topic, tmp_path / "report", **changes)


def report_of(job: Job, topic: str, out: Path, **plan_changes) -> str:
    """The markdown of report ``topic`` built from the store of ``job`` with the plan's study of the job's
    experiment replaced by one whose overrides are the job's (a test's tiny settings make its run an ablation of
    the experiment as configured): the report as the plan would print it for such runs."""
    import dataclasses

    from hrc_lab.report.build import build_report
    from hrc_lab.report.plan import Study
    from hrc_lab.report.plans import PLANS

    plan = PLANS[topic]
    tags = job.run.data.tags
    overrides = tuple(tags.get("variant_overrides", "").split())
    studies = []
    for study in plan.studies:
        if study.mlflow_experiment == tags["experiment"] and study.default:
            study = Study(study.experiment, overrides, key=study.key, title=f"{study.table} (this test's settings)")
        elif study.mlflow_experiment == tags["experiment"]:
            continue
        studies.append(study)
    plan = dataclasses.replace(plan, studies=tuple(studies), **plan_changes)
    return build_report(plan, job.tracking_uri, out).read_text()
