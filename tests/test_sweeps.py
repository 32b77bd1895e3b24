"""A real sweep through the console script and a Hydra launcher: a tiny Table 4.1 sweep (2 methods x 2 seeds) with
hydra/launcher=joblib into a temporary MLflow store, the summary callback's table, then the report built from it.
Slow (CI's slow step): the default suite's subprocess runs are the config-error exit code checks of test_config.py."""

import os
import shutil
import subprocess
import time

import pytest
from mlflow.tracking import MlflowClient

pytestmark = pytest.mark.slow  # real sweeps of subprocesses (~1 min each): CI's slow step runs them

TINY = ["trainer.max_epochs=1", "reasoning.steps=5", "protocol.min_demos=10"]


@pytest.fixture(scope="module")
def joblib_sweep(tmp_path_factory, console_script, migrated_sqlite_template):
    runs = tmp_path_factory.mktemp("sweep") / "runs"
    runs.mkdir()
    shutil.copyfile(migrated_sqlite_template, runs / "mlflow.db")  # the jobs' processes skip MLflow's migrations
    env = dict(os.environ, HRC_LAB_RUNS=str(runs), PYTHONWARNINGS="ignore")
    command = [
        console_script("hrc-lab"),
        "-m",
        "experiment=ch4/table_4_1",
        "hydra/launcher=joblib",
        "hydra.launcher.n_jobs=2",
        "env=package_to_order_2of3",
        "reasoning=ours,mlp",
        "seed=0,1",
        *TINY,
    ]
    result = subprocess.run(command, capture_output=True, text=True, env=env, timeout=250)  # < pytest-timeout
    assert result.returncode == 0, result.stderr[-3000:]
    return f"sqlite:///{runs / 'mlflow.db'}", result.stdout


def sweep_jobs(tracking_uri):
    """The MLflow runs of the sweep's jobs (not the summary callback's run)."""
    client = MlflowClient(tracking_uri)
    experiment = client.get_experiment_by_name("ch4/table_4_1")
    return client, [r for r in client.search_runs([experiment.experiment_id]) if r.data.tags.get("kind") != "summary"]


def test_sweep_lands_as_named_tagged_runs_in_one_experiment(joblib_sweep, base_run_name):
    client, jobs = sweep_jobs(joblib_sweep[0])
    names = sorted(base_run_name(r) for r in jobs)
    assert names == [f"ch4/table_4_1-{m}-2of3-seed{s}" for m in ("mlp", "ours") for s in (0, 1)]
    assert all(r.info.status == "FINISHED" for r in jobs)
    assert len({r.data.tags["sweep"] for r in jobs}) == 1  # the parallel jobs share one sweep id
    for run in jobs:
        tags = run.data.tags
        assert {"chapter", "table", "method", "seed", "sweep"} <= set(tags)
        assert tags["chapter"] == "ch4" and tags["table"] == "table_4_1" and tags["sweep"] != "none"
        assert 0.0 <= run.data.metrics["sr"] <= 1.0
        assert run.data.metrics["latency_ms_batch1"] > 0
        assert run.data.params["reasoning.name"] == run.data.tags["method"]
        history = client.get_metric_history(run.info.run_id, "train_loss")
        assert len(history) == 1  # one value per epoch (max_epochs=1)
        artifacts = {a.path for a in client.list_artifacts(run.info.run_id, "tables")}
        assert {"tables/table_4_1.csv", "tables/table_4_1.md"} <= artifacts
        assert client.list_artifacts(run.info.run_id, "config")
        assert client.list_artifacts(run.info.run_id, "hydra")


def test_sweep_prints_the_summary_table(joblib_sweep):
    _, stdout = joblib_sweep
    assert "Table 4.1" in stdout and "thesis in brackets" in stdout and "| Ours " in stdout


def test_report_command_writes_markdown_and_plot(joblib_sweep, tmp_path, capsys):
    from hrc_lab.report.cli import main as report_main

    tracking_uri, _ = joblib_sweep
    report_main(["ch4_reasoning", "--tracking-uri", tracking_uri, "--out", str(tmp_path)])
    report = (tmp_path / "ch4_reasoning.md").read_text()
    assert "## The thesis' results beside ours" in report and "| MLP | thesis |" in report
    # The sweep's size overrides make its runs a variant no study of the plan names: they are in no section.
    assert {r.data.tags["variant"] for r in sweep_jobs(tracking_uri)[1]} != {"default"}
    assert "Not run yet: `hrc-lab experiment=ch4/table_4_1 hydra/launcher=joblib`" in report
    assert (tmp_path / "ch4_reasoning" / "thesis_tables.md").is_file()
    assert f"wrote {tmp_path / 'ch4_reasoning.md'}" in capsys.readouterr().out


def test_submitit_local_sweep(tmp_path, console_script):
    """submitit's real executor on local processes (the SLURM launcher's code path): a 2-job sweep lands as two
    FINISHED runs from two processes. Slow (~40 s): CI runs it in its own step."""
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher", reason='pip install -e ".[cluster]"')
    runs = tmp_path / "runs"
    env = dict(os.environ, HRC_LAB_RUNS=str(runs), PYTHONWARNINGS="ignore")
    command = [console_script("hrc-lab"), "-m", "experiment=ch4/table_4_1", "hydra/launcher=submitit_local",
               "hydra.launcher.timeout_min=10", "env=package_to_order_2of3", "reasoning=ours,mlp", "seed=0", *TINY]
    result = subprocess.run(command, capture_output=True, text=True, env=env, timeout=250)
    assert result.returncode == 0, result.stderr[-3000:]
    _, jobs = sweep_jobs(f"sqlite:///{runs / 'mlflow.db'}")
    assert sorted(r.data.tags["method"] for r in jobs) == ["mlp", "ours"]
    assert all(r.info.status == "FINISHED" for r in jobs)
    assert len({r.data.tags["pid"] for r in jobs}) == 2  # one process per job


def test_ray_launcher_sweep(tmp_path, console_script):
    """hydra-ray-launcher's local launcher (hydra/launcher=ray) starts a local Ray instance, runs a 2-job sweep as
    two FINISHED runs from two Ray worker processes, and every socket Ray listens on is loopback. Needs the separate
    venv of `pip install -e ".[dev,ray]"` (skipped elsewhere). Slow (~45 s)."""
    pytest.importorskip("hydra_plugins.hydra_ray_launcher", reason='pip install -e ".[dev,ray]" (its own venv)')
    psutil = pytest.importorskip("psutil")  # a dependency of ray
    runs = tmp_path / "runs"
    # On Linux, Ray advertises (and its agents bind) the outward IP unless this is 0; with 0 it uses 127.0.0.1.
    env = dict(os.environ, HRC_LAB_RUNS=str(runs), PYTHONWARNINGS="ignore", RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER="0")
    command = [console_script("hrc-lab"), "-m", "experiment=ch4/table_4_1", "hydra/launcher=ray",
               "+hydra.launcher.ray.init.include_dashboard=false", "+hydra.launcher.ray.init.num_cpus=2",
               "env=package_to_order_2of3", "reasoning=ours,mlp", "seed=0", *TINY]
    listening = set()
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                          start_new_session=True) as proc:
        deadline = time.monotonic() + 250
        while proc.poll() is None and time.monotonic() < deadline:
            try:
                pids = {proc.pid} | {c.pid for c in psutil.Process(proc.pid).children(recursive=True)}
                pids |= {p.pid for p in psutil.process_iter() if _same_session(p, proc.pid)}  # Ray daemons
                listening |= {(c.pid, c.laddr.ip) for c in psutil.net_connections("inet")
                              if c.status == psutil.CONN_LISTEN and c.pid in pids}
            except psutil.Error:
                pass
            time.sleep(1)
        if proc.poll() is None:
            os.killpg(proc.pid, 9)
        output = proc.stdout.read()
    assert proc.returncode == 0, output[-3000:]
    subprocess.run([console_script("ray"), "stop"], capture_output=True, timeout=60)
    assert listening, "saw no listening socket while Ray ran"
    assert {ip for _, ip in listening} <= {"127.0.0.1", "::ffff:127.0.0.1"}, listening
    _, jobs = sweep_jobs(f"sqlite:///{runs / 'mlflow.db'}")
    assert sorted(r.data.tags["method"] for r in jobs) == ["mlp", "ours"]
    assert all(r.info.status == "FINISHED" for r in jobs)
    assert len({r.data.tags["pid"] for r in jobs}) == 2  # one Ray worker process per job


def _same_session(process, leader: int) -> bool:
    try:
        return os.getsid(process.pid) == leader
    except (OSError, ProcessLookupError):
        return False
