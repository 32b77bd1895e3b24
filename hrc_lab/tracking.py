"""MLflow bookkeeping: one MLflow run per Hydra job, with a readable name, tags, the resolved config, metrics,
tables and plots. Talks to MLflow through ``MlflowClient`` (no global "active run"), so jobs of a joblib sweep
never share state; the tracking URI is one config key (``logger.tracking_uri``), a local sqlite file by default.
"""

from __future__ import annotations

import functools
import os
import re
import socket
import tempfile
import time
from dataclasses import MISSING, dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import requests
from lightning.pytorch.loggers import MLFlowLogger
from mlflow.entities import Metric, Param
from mlflow.exceptions import MlflowException
from mlflow.tracking import MlflowClient
from omegaconf import DictConfig, OmegaConf, open_dict

from hrc_lab.config import ConfigError, LoggerConfig, register_schemas, validate_config
from hrc_lab.interrupts import RunInterrupted
from hrc_lab.processes import code_identity, machine_identity, process_start
from hrc_lab.run_naming import CONF_DIR, NEUTRAL_KEYS

# A job logging to a tracking server gives up on it within ~30 s (MLflow's defaults retry for minutes: 7 retries,
# backoff factor 2, 120 s per request); each is a default the user's environment may set otherwise.
SERVER_REQUEST_ENV = {"MLFLOW_HTTP_REQUEST_MAX_RETRIES": "2", "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR": "1",
                      "MLFLOW_HTTP_REQUEST_TIMEOUT": "10"}


class TrackingUnavailable(RuntimeError):
    """The tracking server did not answer; the message names it and what to do."""


class ServerClient:
    """An ``MlflowClient`` of a tracking server whose failures to reach the server (or the server's to reach its
    database) raise :class:`TrackingUnavailable` with a message naming the server, instead of MLflow's traceback."""

    def __init__(self, tracking_uri: str) -> None:
        for key, value in SERVER_REQUEST_ENV.items():
            os.environ.setdefault(key, value)
        self._client, self.tracking_uri = MlflowClient(tracking_uri), tracking_uri

    def __getattr__(self, name: str):
        attribute = getattr(self._client, name)
        if not callable(attribute):
            return attribute

        def call(*args, **kwargs):
            try:
                return attribute(*args, **kwargs)
            except (MlflowException, requests.RequestException) as err:
                if isinstance(err, MlflowException) and not unreachable(err):
                    raise
                raise TrackingUnavailable(
                    f"the tracking server {self.tracking_uri} did not answer ({str(err).splitlines()[0][:300]}). "
                    "Check it with `hrc-lab-server status`, restart it with `hrc-lab-server start`, then "
                    "`hrc-lab-runs stale --tracking-uri ...` marks the runs it lost KILLED") from err

        return call


def unreachable(err: MlflowException) -> bool:
    """An MLflow error that says the server could not be reached or could not serve (5xx), not a refused request."""
    return str(err).startswith("API request to") or err.get_http_status_code() >= 500


def tracking_client(tracking_uri: str) -> MlflowClient | ServerClient:
    """The client of a resolved tracking URI: a :class:`ServerClient` for a server (http, https), else MLflow's."""
    served = tracking_uri.startswith(("http://", "https://"))
    return ServerClient(tracking_uri) if served else MlflowClient(tracking_uri)


def resolve_tracking_uri(uri: str) -> str:
    """Make a relative sqlite path absolute (jobs may run in other working directories) and create its folder."""
    match = re.fullmatch(r"sqlite:///(.+)", uri)
    if match and not Path(match.group(1)).is_absolute():
        path = Path(match.group(1)).resolve()
        path.parent.mkdir(parents=True, exist_ok=True)
        return f"sqlite:///{path}"
    return uri


def ensure_experiment(client: MlflowClient, name: str, artifact_root: str) -> str:
    """The id of the MLflow experiment ``name``, created with artifacts under ``artifact_root`` if new."""
    experiment = client.get_experiment_by_name(name)
    if experiment is not None:
        return experiment.experiment_id
    location = None
    # A local artifact folder only for a local store: a server (http) keeps artifacts itself (proxied), so every
    # client's runs land in the same place.
    served = client.tracking_uri.startswith(("http://", "https://"))
    if not served and ("://" not in artifact_root or artifact_root.startswith("file:")):
        folder = Path(artifact_root.removeprefix("file://")).resolve() / re.sub(r"[^\w.-]+", "_", name)
        location = folder.as_uri()
    try:
        return client.create_experiment(name, artifact_location=location)
    except Exception:  # another job of the sweep created it first
        experiment = client.get_experiment_by_name(name)
        if experiment is None:
            raise
        return experiment.experiment_id


MAX_PARAM = 6000  # MLflow keeps the first 6000 characters of a param (RunTracker.log_config)


def changed_settings(logged: dict[str, str], config: dict[str, str], defaults: dict[str, str] | None = None
                     ) -> list[str]:
    """The keys a run logged (``logged``: its params) to which ``config`` (a flattened config, :func:`flatten`) gives
    another value, or which it lacks, and the keys of ``config`` the run did not log (added since it ran) to a node it
    logged other keys of, that ``config`` sets away from their schema default (``defaults``: :func:`schema_defaults`;
    the key was added with a default that keeps what ran before, so the run ran with that default); sorted. The one
    rule by which a resume, a report and ``hrc-lab-runs`` read an older run under today's config."""
    changed = {key for key, value in logged.items() if key not in config or config[key][:MAX_PARAM] != value}
    nodes = {key.rsplit(".", 1)[0] for key in logged if "." in key}  # a key is new to a node the run had
    changed |= {key for key, value in config.items() if key not in logged and key in (defaults or {})
                and defaults[key] != value and key.rsplit(".", 1)[0] in nodes}
    return sorted(changed)


def schema_defaults(cfg: DictConfig) -> dict[str, str]:
    """Each setting of ``cfg`` as the schema of its node (the dataclass a group's config extends) defaults it,
    flattened as :func:`flatten` flattens ``cfg``; settings of nodes without a schema, or without a default, are left
    out. What a run that did not log a key (added since) ran with: :func:`changed_settings`."""
    out: dict[str, str] = {}

    def walk(node: DictConfig, prefix: str) -> None:
        schema = OmegaConf.get_type(node)
        declared = {f.name: f for f in fields(schema)} if is_dataclass(schema) else {}
        for key in node:
            value = node._get_node(key)
            if isinstance(value, DictConfig) and not value._is_none():
                walk(value, f"{prefix}{key}.")
            elif key in declared and declared[key].default is not MISSING:
                out.update(flatten({key: declared[key].default}, prefix))
            elif key in declared and declared[key].default_factory is not MISSING:
                out.update(flatten({key: declared[key].default_factory()}, prefix))

    walk(cfg, "")
    return out


def flatten(node, prefix: str = "") -> dict[str, str]:
    """Dotted keys of a resolved config, for MLflow params."""
    out: dict[str, str] = {}
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for key, value in items:
        full = f"{prefix}{key}"
        if isinstance(value, (dict, list)) and value:
            out.update(flatten(value, full + "."))
        else:
            out[full] = str(value)
    return out


def job_settings(cfg: DictConfig) -> dict[str, str]:
    """The flattened, resolved settings of ``cfg`` that make its job: all but the neutral groups' (where a run logs
    and writes, :data:`hrc_lab.run_naming.NEUTRAL_KEYS`) and those interpolated from them."""
    neutral_reference = re.compile(r"\$\{(" + "|".join(NEUTRAL_KEYS) + r")\.")
    resolved = flatten(OmegaConf.to_container(cfg, resolve=True))
    raw = flatten(OmegaConf.to_container(cfg, resolve=False))
    return {key: value for key, value in resolved.items()
            if key.split(".")[0] not in NEUTRAL_KEYS and not neutral_reference.search(raw.get(key, ""))}


@functools.cache
def _composed_groups(overrides: tuple[str, ...]) -> DictConfig:
    """The config the group-choosing ``overrides`` compose from today's ``conf/``, without its ``hydra`` node
    (cached: callers copy it)."""
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra._internal.utils import create_config_search_path
    from hydra.core.plugins import Plugins
    from hydra.types import RunMode

    register_schemas()
    Plugins.instance()
    loader = ConfigLoaderImpl(config_search_path=create_config_search_path(str(CONF_DIR)))
    cfg = loader.load_configuration("config", list(overrides), RunMode.RUN)
    with open_dict(cfg):
        del cfg["hydra"]
    return cfg


def _chooses_a_config(override: str) -> bool:
    """A group choice (``env=...``, ``hydra/launcher=...``) or an addition / deletion, as opposed to a value."""
    key = override.split("=", 1)[0]
    return key.startswith(("+", "~")) or "/" in key or ("." not in key and (CONF_DIR / key).is_dir())


def compose_today(overrides: tuple[str, ...]) -> DictConfig:
    """The config (no ``hydra`` node) that ``overrides`` (a job's task overrides) compose from today's ``conf/``,
    as ``hydra.compose`` would; :class:`ConfigError` with the first line of the reason when they no longer compose
    (an option or key that no longer exists, a value its schema no longer accepts). The group choices are composed
    once per set (cached), the values then set on a copy."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        cfg = _composed_groups(tuple(o for o in overrides if _chooses_a_config(o))).copy()
        for override in OverridesParser.create().parse_overrides([o for o in overrides if not _chooses_a_config(o)]):
            OmegaConf.update(cfg, override.key_or_group, override.value(), merge=True)
    except Exception as err:  # Hydra's and OmegaConf's errors, whose first line names the key or option
        raise ConfigError(str(err).splitlines()[0] if str(err) else type(err).__name__) from err
    return cfg


@functools.cache
def composed_today(overrides: tuple[str, ...]) -> dict[str, str] | None:
    """:func:`job_settings` of :func:`compose_today`, or None when ``overrides`` no longer compose or resolve
    (cached, for the reports' thousands of runs: treat the result as read-only)."""
    try:
        return job_settings(compose_today(overrides))
    except Exception:  # no longer composes (ConfigError), or an interpolation that no longer resolves
        return None


@functools.cache
def schema_defaults_today(overrides: tuple[str, ...]) -> dict[str, str]:
    """:func:`schema_defaults` of :func:`compose_today` (empty when ``overrides`` no longer compose; cached, as
    :func:`composed_today`)."""
    try:
        return schema_defaults(compose_today(overrides))
    except ConfigError:
        return {}


def process_identity(pid: int | None = None) -> dict[str, str]:
    """Tags that identify the process running a job: host, PID and the process' start (boot id and start time in
    clock ticks), so a later look can tell a live job from a dead one whose PID was reused."""
    pid = os.getpid() if pid is None else pid
    return {"host": socket.gethostname(), "pid": str(pid), "process_start": process_start(pid) or "unknown"}


class RunTracker:
    """One MLflow run, tagged with :func:`process_identity`, :func:`machine_identity` and
    :func:`~hrc_lab.processes.code_identity`; use as a context manager:
    leaving it normally marks the run FINISHED, an exception FAILED, SIGTERM/SIGINT (:class:`RunInterrupted`)
    KILLED with the signal in the ``signal`` tag. ``parent_run_id`` names the killed run this one resumes (tag
    ``resumed_from``); its checkpoints are read by :meth:`resume_checkpoint`."""

    def __init__(self, cfg: LoggerConfig, experiment: str, run_name: str, tags: dict[str, str],
                 parent_run_id: str | None = None) -> None:
        self.tracking_uri = resolve_tracking_uri(cfg.tracking_uri)
        self.client = tracking_client(self.tracking_uri)
        self.experiment_id = ensure_experiment(self.client, experiment, cfg.artifact_root)
        self.run_name = run_name
        self.tags = {**tags, **process_identity(), **machine_identity(), **code_identity()}
        if parent_run_id:
            self.tags["resumed_from"] = parent_run_id
        self.parent_run_id = parent_run_id
        self.run_id: str | None = None
        self._downloads: tempfile.TemporaryDirectory | None = None

    def __enter__(self) -> RunTracker:
        run = self.client.create_run(self.experiment_id, run_name=self.run_name, tags=self.tags)
        self.run_id = run.info.run_id
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if isinstance(exc, RunInterrupted):
            self.client.set_tag(self.run_id, "signal", exc.signal_name)
            exc.killed_run_id = self.run_id
            status = "KILLED"
        else:
            status = "FAILED" if exc_type else "FINISHED"
        self.client.set_terminated(self.run_id, status)
        if self._downloads is not None:
            self._downloads.cleanup()

    def resume_checkpoint(self, artifact: str) -> Path | None:
        """The resumed run's checkpoint ``artifact`` (e.g. ``checkpoints/ndp/last.ckpt``) downloaded to a local
        file, or None when no run of the chain saved one (the fit then starts from scratch). A resumed run killed
        before its first checkpoint saved none of its own: its checkpoint is then the one it resumed from, so the
        chain of ``resumed_from`` tags is followed to the nearest run that holds ``artifact``."""
        folder, _, name = artifact.rpartition("/")
        source = self.parent_run_id
        while source is not None and name not in {Path(f.path).name for f in
                                                  self.client.list_artifacts(source, folder)}:
            source = self.client.get_run(source).data.tags.get("resumed_from")
        if source is None:
            return None
        if self._downloads is None:
            self._downloads = tempfile.TemporaryDirectory(prefix="hrc_lab_resume_")
        return Path(self.client.download_artifacts(source, artifact, self._downloads.name))

    def copy_history(self, last_step: int, after_step: int = -1, keys: tuple[str, ...] | None = None) -> None:
        """The metric values of steps ``after_step`` < step <= ``last_step`` (every metric, or ``keys``) of the
        runs this one continues into this run, with their timestamps, so that it holds the whole curve of the
        checkpoint it resumes. The ``resumed_from`` chain is followed back; a step takes the value of the nearest
        run that logged it (a resumed run re-trained the steps after its checkpoint)."""
        taken: dict[str, dict[int, Metric]] = {}
        source = self.parent_run_id
        while source is not None:
            run = self.client.get_run(source)
            for key in keys if keys is not None else run.data.metrics:
                history = sorted(self.client.get_metric_history(source, key), key=lambda m: m.timestamp)
                own = {m.step: Metric(key, m.value, m.timestamp, m.step) for m in history
                       if after_step < m.step <= last_step}  # a run's latest value of a step
                taken[key] = {**own, **taken.get(key, {})}  # nearer runs win
            source = run.data.tags.get("resumed_from")
        batch = [metric for steps in taken.values() for metric in steps.values()]
        for start in range(0, len(batch), 500):
            self.client.log_batch(self.run_id, metrics=batch[start : start + 500])

    # logging -------------------------------------------------------------------------------------------------
    def log_config(self, cfg: DictConfig) -> None:
        resolved = OmegaConf.to_container(cfg, resolve=True)
        params = [Param(k, v[:MAX_PARAM]) for k, v in flatten(resolved).items()]
        for start in range(0, len(params), 100):
            self.client.log_batch(self.run_id, params=params[start : start + 100])
        self.log_text(OmegaConf.to_yaml(cfg, resolve=True), "config/resolved.yaml")

    def log_metrics(self, metrics: dict[str, float], step: int = 0) -> None:
        now = int(time.time() * 1000)
        batch = [Metric(k, float(v), now, step) for k, v in metrics.items()]
        for start in range(0, len(batch), 500):
            self.client.log_batch(self.run_id, metrics=batch[start : start + 500])

    def log_text(self, text: str, artifact_file: str) -> None:
        self.client.log_text(self.run_id, text, artifact_file)

    def log_artifact(self, path: Path, artifact_path: str | None = None) -> None:
        path = Path(path)
        if path.is_dir():
            self.client.log_artifacts(self.run_id, str(path), artifact_path)
        elif path.exists():
            self.client.log_artifact(self.run_id, str(path), artifact_path)

    def log_table(self, table: pd.DataFrame, name: str) -> None:
        """A result table as CSV and markdown artifacts under ``tables/``."""
        self.log_text(table.to_csv(index=False), f"tables/{name}.csv")
        self.log_text(table.to_markdown(index=False), f"tables/{name}.md")

    def log_figure(self, figure, artifact_file: str) -> None:
        self.client.log_figure(self.run_id, figure, artifact_file)

    def log_torch_model(self, model, artifact_file: str) -> None:
        import torch

        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / Path(artifact_file).name
            torch.save(model.state_dict(), path)
            self.log_artifact(path, str(Path(artifact_file).parent))

    def lightning_logger(self, prefix: str = ""):
        """A Lightning MLFlowLogger writing per-epoch metrics into this run (keys ``<prefix>-train_loss``)."""
        return SharedRunLogger(tracking_uri=self.tracking_uri, run_id=self.run_id, prefix=prefix)


class SharedRunLogger(MLFlowLogger):
    """An MLFlowLogger that leaves the run open when a fit ends: one job trains several models into one run,
    and :class:`RunTracker` closes it."""

    def finalize(self, status: str = "success") -> None:
        pass


@dataclass
class SavedRun:
    """A run as a script replays it: its validated config, seed and the folder of the artifacts it asked for."""

    cfg: Any
    seed: int
    folder: Path


def saved_run(client: MlflowClient, run_id: str, directory: str, artifacts: str = "agents") -> SavedRun:
    """Download run ``run_id``'s resolved config and its ``artifacts`` folder (e.g. a Ch.3 run's saved agents,
    ``agents/subtask<k>/``) into ``directory``, the config validated."""
    register_schemas()
    cfg = validate_config(OmegaConf.load(client.download_artifacts(run_id, "config/resolved.yaml", directory)))
    folder = Path(client.download_artifacts(run_id, artifacts, directory))
    return SavedRun(cfg, int(client.get_run(run_id).data.params["seed"]), folder)
