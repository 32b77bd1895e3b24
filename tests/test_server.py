"""The team tracking server end to end: ``hrc-lab-server start`` (a fresh PostgreSQL cluster + MLflow, free ports),
a 2-job joblib sweep logging to it over http, a report built from it, then stop, start again on the same data and
the runs are still there. Skips when PostgreSQL or the psycopg driver (the ``team`` extra) is not installed."""

import json
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import pytest
from mlflow.tracking import MlflowClient

from hrc_lab import server

TINY = ["trainer.max_epochs=1", "reasoning.steps=5", "protocol.min_demos=10"]


def missing_requirement() -> str | None:
    try:
        import psycopg  # noqa: F401
    except ImportError:
        return 'psycopg is not installed (pip install -e ".[team]")'
    for program in ("initdb", "pg_ctl"):
        try:
            server.pg_bin(program)
        except server.ServerError as error:
            return str(error)
    if os.geteuid() == 0:
        if shutil.which("runuser") is None:
            return "running as root needs runuser to start PostgreSQL as the postgres user"
        if subprocess.run(["id", "postgres"], capture_output=True).returncode != 0:
            return "running as root needs a postgres user to run PostgreSQL"
    return None


# slow (~95 s: PostgreSQL and MLflow start twice): CI runs it in its slow step (.ci/run)
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(missing_requirement() is not None, reason=f"no team server: {missing_requirement()}")]


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture
def server_dir(tmp_path):
    """The server folder. As root, the postgres user must enter it, and pytest's tmp folders are private to root:
    use a fresh folder directly in /tmp then."""
    if os.geteuid() != 0:
        yield tmp_path / "server"
        return
    folder = Path(tempfile.mkdtemp(prefix="hrc_lab_server_"))
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_server_serves_a_sweep_and_keeps_its_runs_across_a_restart(server_dir, tmp_path, console_script):
    port, pg_port = free_port(), free_port()
    uri = f"http://127.0.0.1:{port}"
    env = dict(os.environ, HRC_LAB_RUNS=str(tmp_path / "runs"), PYTHONWARNINGS="ignore")
    control = [console_script("hrc-lab-server")]
    start = [*control, "start", "--dir", str(server_dir), "--port", str(port), "--pg-port", str(pg_port),
             "--timeout", "60"]

    def call(command, timeout):
        result = subprocess.run(command, capture_output=True, text=True, env=env, timeout=timeout)
        assert result.returncode == 0, f"{command[:3]} exited {result.returncode}:\n{result.stderr[-3000:]}"
        return result.stdout

    try:
        assert f"logger.tracking_uri={uri}" in call(start, 90)
        assert f"logger.tracking_uri={uri}" in call([*control, "status", "--dir", str(server_dir)], 30)

        call([console_script("hrc-lab"), "-m", "experiment=ch4/table_4_1", "hydra/launcher=joblib",
              "env=package_to_order_2of3", "reasoning=ours,mlp", "seed=0", *TINY, f"logger.tracking_uri={uri}"], 150)
        assert not (tmp_path / "runs" / "mlflow.db").exists()  # nothing went to the local store
        assert not (tmp_path / "runs" / "mlartifacts").exists()  # artifacts went to the server
        assert any((server_dir / "artifacts").rglob("table_4_1.csv"))

        out = tmp_path / "report"
        out.mkdir()
        call([console_script("hrc-lab-report"), "ch4_reasoning", "--tracking-uri", uri, "--out", str(out)], 60)
        report = (out / "ch4_reasoning.md").read_text()
        assert "| Ours" in report and "| MLP" in report

        assert "stopped mlflow" in call([*control, "stop", "--dir", str(server_dir)], 60)
        status = subprocess.run([*control, "status", "--dir", str(server_dir)], capture_output=True, text=True,
                                env=env, timeout=30)
        assert status.returncode == 3 and "not running" in status.stdout

        call(start, 90)
        client = MlflowClient(uri)
        experiment = client.get_experiment_by_name("ch4/table_4_1")
        jobs = [r for r in client.search_runs([experiment.experiment_id]) if r.data.tags.get("kind") != "summary"]
        assert sorted(r.data.tags["method"] for r in jobs) == ["mlp", "ours"]
        assert all(r.info.status == "FINISHED" for r in jobs)
        assert {"tables/table_4_1.csv"} <= {a.path for a in client.list_artifacts(jobs[0].info.run_id, "tables")}

        # its database killed under it (issue 49): status says so and exits 3, start brings both back with the runs
        os.kill(json.loads((server_dir / "server.json").read_text())["pg_pid"], signal.SIGKILL)
        time.sleep(2)
        status = subprocess.run([*control, "status", "--dir", str(server_dir)], capture_output=True, text=True,
                                env=env, timeout=60)
        assert status.returncode == 3 and "database does not answer" in status.stdout, status.stdout
        assert f"logger.tracking_uri={uri}" in call(start, 120)
        runs = [r for r in MlflowClient(uri).search_runs([experiment.experiment_id])
                if r.data.tags.get("kind") != "summary"]
        assert len(runs) == 2
    finally:
        if (server_dir / "server.json").exists():
            subprocess.run([*control, "stop", "--dir", str(server_dir)], env=env, timeout=90)
