"""``hrc-lab-server``: a team MLflow tracking server backed by PostgreSQL, artifacts proxied by the server.

    hrc-lab-server start [--db-uri URI] [--port 5000] [--pg-port 5433] [--dir runs/server]
    hrc-lab-server status [--dir runs/server]
    hrc-lab-server stop [--dir runs/server]

Without ``--db-uri`` it initialises (once) a local PostgreSQL cluster in ``<dir>/postgres`` (as root: owned by and
run as the ``postgres`` user), starts it on 127.0.0.1 only, creates the database ``mlflow`` and serves MLflow on
127.0.0.1 with artifacts in ``<dir>/artifacts``. The PIDs of the processes it started are kept in
``<dir>/server.json``; ``stop`` stops exactly those (MLflow's process group, then ``pg_ctl stop``), and ``start``
again serves the same data. Jobs log to it with ``logger.tracking_uri=http://127.0.0.1:<port>``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

from hrc_lab.config import runs_dir
from hrc_lab.processes import alive, process_start, stop_group

PG_BIN_DIRS = [Path("/usr/lib/postgresql/15/bin")]
LOOPBACK = {"127.0.0.1", "localhost", "::1"}
DATABASE = "mlflow"


class ServerError(RuntimeError):
    """A start/stop failure with a message for the user."""


# processes ----------------------------------------------------------------------------------------------------------
def port_free(port: int, host: str = "127.0.0.1") -> bool:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the servers do: TIME_WAIT is no obstacle
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True


def healthy(url: str, timeout: float = 2.0) -> bool:
    """MLflow's process answers (``/health``; it says OK with its database gone)."""
    try:
        with urllib.request.urlopen(f"{url}/health", timeout=timeout) as response:
            return response.status == 200
    except (urllib.error.URLError, OSError):
        return False


def database_answers(url: str, timeout: float = 5.0) -> bool:
    """The server can read its database: a one-experiment search through MLflow's REST API succeeds."""
    try:
        with urllib.request.urlopen(f"{url}/api/2.0/mlflow/experiments/search?max_results=1",
                                    timeout=timeout) as response:
            return response.status == 200
    except (urllib.error.URLError, OSError):
        return False


def log_tail(path: Path, lines: int = 30) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return "(no log)"


# PostgreSQL ---------------------------------------------------------------------------------------------------------
def pg_bin(name: str) -> str:
    """Path of a PostgreSQL program: the PG_BIN_DIRS (or $HRC_LAB_PG_BIN) folder, else PATH."""
    folders = [Path(os.environ["HRC_LAB_PG_BIN"])] if os.environ.get("HRC_LAB_PG_BIN") else PG_BIN_DIRS
    for folder in folders:
        if (folder / name).is_file():
            return str(folder / name)
    found = shutil.which(name)
    if found is None:
        raise ServerError(f"PostgreSQL's {name} not found (looked in {', '.join(map(str, folders))} and PATH); "
                          "install PostgreSQL or pass --db-uri")
    return found


def as_pg_user(command: list[str]) -> list[str]:
    """Run ``command`` as the ``postgres`` user when we are root (PostgreSQL refuses to run as root)."""
    if os.geteuid() != 0:
        return command
    runuser = shutil.which("runuser")
    if runuser is None:
        raise ServerError("running as root needs runuser to start PostgreSQL as the postgres user")
    return [runuser, "-u", "postgres", "--", *command]


def give_to_pg_user(path: Path) -> None:
    if os.geteuid() == 0:
        shutil.chown(path, "postgres", "postgres")


def check_reachable(folder: Path) -> None:
    """As root, the postgres user must be able to enter every parent of the cluster folder."""
    if os.geteuid() != 0:
        return
    for parent in [*reversed(folder.parents)]:
        if subprocess.run(as_pg_user(["test", "-x", str(parent)]), capture_output=True).returncode != 0:
            raise ServerError(f"the postgres user cannot enter {parent} (mode {parent.stat().st_mode & 0o777:o}); "
                              f"choose a --dir it can reach, or chmod o+x {parent}")


def run(command: list[str], what: str, timeout: float = 120) -> None:
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    if result.returncode != 0:
        raise ServerError(f"{what} failed ({' '.join(command)}):\n{(result.stdout + result.stderr)[-3000:]}")


def pg_running(data: Path) -> int | None:
    """PID of the postmaster serving ``data``, or None."""
    try:
        pid = int((data / "postmaster.pid").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None
    return pid if process_start(pid) else None


def start_postgres(root: Path, port: int, timeout: float) -> dict:
    """Initialise (once) and start the local cluster in ``root/postgres``; create the database. Returns its state."""
    data = root / "postgres"
    log = root / "postgres.log"
    check_reachable(root)
    if not (data / "PG_VERSION").exists():
        data.mkdir(mode=0o700, exist_ok=True)
        give_to_pg_user(data)
        run(as_pg_user([pg_bin("initdb"), "-D", str(data), "-A", "trust", "-U", "postgres", "-E", "UTF8",
                        "--no-locale"]), "initdb", timeout)
    pid = pg_running(data)
    started = False
    if pid is None:
        if not port_free(port):
            raise ServerError(f"port {port} (PostgreSQL) is in use on 127.0.0.1; choose another --pg-port")
        log.touch()
        give_to_pg_user(log)
        # TCP on 127.0.0.1 only, no unix socket (no path-length limit, nothing in /var/run); trust auth is safe
        # only because nothing but this machine can connect.
        options = f"-p {port} -h 127.0.0.1 -c unix_socket_directories=''"
        try:
            run(as_pg_user([pg_bin("pg_ctl"), "-D", str(data), "-l", str(log), "-w", "-t", str(int(timeout)),
                            "-o", options, "start"]), "pg_ctl start", timeout + 10)
        except ServerError as error:
            raise ServerError(f"{error}\n--- {log} ---\n{log_tail(log)}") from None
        pid = pg_running(data)
        started = True
    else:
        port = pg_port_of(data, port)
    create_database(port)
    return {"pg_data": str(data), "pg_port": port, "pg_pid": pid, "pg_start": process_start(pid) if pid else None,
            "pg_started_here": started, "pg_log": str(log)}


def pg_port_of(data: Path, default: int) -> int:
    """The port a running cluster listens on (line 4 of postmaster.pid)."""
    try:
        return int((data / "postmaster.pid").read_text().splitlines()[3])
    except (OSError, ValueError, IndexError):
        return default


def create_database(port: int) -> None:
    try:
        import psycopg
    except ImportError:
        raise ServerError('the PostgreSQL driver is missing: pip install -e ".[team]"') from None
    with psycopg.connect(host="127.0.0.1", port=port, user="postgres", dbname="postgres", autocommit=True,
                         connect_timeout=10) as connection:
        if connection.execute("SELECT 1 FROM pg_database WHERE datname = %s", (DATABASE,)).fetchone() is None:
            connection.execute(f'CREATE DATABASE "{DATABASE}"')


def stop_postgres(data: Path, timeout: float = 60) -> None:
    if pg_running(data) is not None:
        run(as_pg_user([pg_bin("pg_ctl"), "-D", str(data), "-m", "fast", "-w", "-t", str(int(timeout)), "stop"]),
            "pg_ctl stop", timeout + 10)


# MLflow -------------------------------------------------------------------------------------------------------------
def start_mlflow(root: Path, db_uri: str, host: str, port: int, timeout: float) -> dict:
    artifacts = root / "artifacts"
    artifacts.mkdir(parents=True, exist_ok=True)
    log = root / "mlflow.log"
    command = [sys.executable, "-m", "mlflow", "server", "--backend-store-uri", db_uri,
               "--artifacts-destination", str(artifacts.resolve()), "--host", host, "--port", str(port),
               "--workers", "1"]
    # MLflow 3's job runner (GenAI scorers, trace roll-ups; nothing hrc_lab uses) adds seven busy worker processes:
    # off unless the environment asks for it.
    env = {"MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false", **os.environ}
    with open(log, "ab") as out:
        process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                   start_new_session=True, cwd=root, env=env)
    start = process_start(process.pid)
    url = f"http://{host}:{port}"
    deadline = time.monotonic() + timeout
    while not healthy(url):
        if process.poll() is not None or time.monotonic() > deadline:
            why = f"exited with code {process.returncode}" if process.poll() is not None else \
                f"did not answer on {url} within {timeout:.0f} s"
            stop_group(process.pid, start)
            raise ServerError(f"mlflow server {why}\n--- {log} ---\n{log_tail(log)}")
        time.sleep(0.5)
    return {"mlflow_pid": process.pid, "mlflow_start": start, "mlflow_log": str(log), "host": host, "port": port,
            "tracking_uri": url}


# commands -----------------------------------------------------------------------------------------------------------
def state_file(root: Path) -> Path:
    return root / "server.json"


def read_state(root: Path) -> dict | None:
    try:
        return json.loads(state_file(root).read_text())
    except (OSError, ValueError):
        return None


def start(root: Path, db_uri: str | None, host: str, port: int, pg_port: int, timeout: float) -> dict:
    if host not in LOOPBACK:
        raise ServerError(f"--host {host}: only loopback addresses ({', '.join(sorted(LOOPBACK))}) are served; put "
                          "an authenticating reverse proxy in front to share beyond this machine")
    root = root.resolve()
    root.mkdir(parents=True, exist_ok=True)
    state = read_state(root)
    if state and alive(state.get("mlflow_pid"), state.get("mlflow_start")):
        if database_answers(state["tracking_uri"]):
            raise ServerError(f"already running: {state['tracking_uri']} (pid {state['mlflow_pid']}); "
                              f"hrc-lab-server stop --dir {root}")
        stop(root)  # half dead (e.g. its database was killed): stop what is left, then start both again
    elif state:
        stop(root)  # MLflow is gone; stop a database it left running and forget the old state
    if not port_free(port, "::1" if host == "::1" else "127.0.0.1"):
        raise ServerError(f"port {port} is in use on {host}; choose another --port")
    if os.geteuid() == 0:
        root.chmod(root.stat().st_mode | 0o001)  # the postgres user enters root/ to reach its cluster folder
    pg: dict = {}
    if db_uri is None:
        pg = start_postgres(root, pg_port, timeout)
        db_uri = f"postgresql+psycopg://postgres@127.0.0.1:{pg['pg_port']}/{DATABASE}"
    try:
        server = start_mlflow(root, db_uri, host, port, timeout)
    except BaseException:
        if pg.get("pg_started_here"):
            stop_postgres(Path(pg["pg_data"]))
        raise
    state = {"db_uri": db_uri, **pg, **server, "started_at": time.strftime("%Y-%m-%dT%H:%M:%S")}
    state_file(root).write_text(json.dumps(state, indent=2) + "\n")
    return state


def stop(root: Path) -> list[str]:
    root = root.resolve()
    state = read_state(root)
    if state is None:
        raise ServerError(f"no server recorded in {state_file(root)}")
    done = []
    if alive(state.get("mlflow_pid"), state.get("mlflow_start")):
        stop_group(state["mlflow_pid"], state["mlflow_start"])
        done.append(f"stopped mlflow (pid {state['mlflow_pid']})")
    if state.get("pg_data") and pg_running(Path(state["pg_data"])) is not None:
        stop_postgres(Path(state["pg_data"]))
        done.append(f"stopped PostgreSQL (pid {state.get('pg_pid')})")
    state_file(root).unlink()
    return done or ["nothing was running"]


def status(root: Path) -> tuple[bool, str]:
    root = root.resolve()
    state = read_state(root)
    if state is None:
        return False, f"not running (no {state_file(root)})"
    up = alive(state.get("mlflow_pid"), state.get("mlflow_start"))
    answers = up and healthy(state["tracking_uri"])
    reads = answers and database_answers(state["tracking_uri"])
    lines = [f"mlflow: {'running' if up else 'not running'} (pid {state.get('mlflow_pid')}), "
             f"{'answers' if answers else 'does not answer'} on {state['tracking_uri']}"
             + ("" if reads or not answers else "; its database does not answer: `hrc-lab-server start` restarts "
                                                 "both, then `hrc-lab-runs stale` marks the interrupted runs")]
    if state.get("pg_data"):
        pid = pg_running(Path(state["pg_data"]))
        running = f"running (pid {pid})" if pid else "not running"
        lines.append(f"postgres: {running} on 127.0.0.1:{state['pg_port']}, data {state['pg_data']}")
    else:
        lines.append("database: given by --db-uri")
    if reads:
        lines.append(f"logger.tracking_uri={state['tracking_uri']}")
    return bool(reads), "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="hrc-lab-server", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    start_parser = commands.add_parser("start", help="start PostgreSQL (unless --db-uri) and the MLflow server")
    start_parser.add_argument("--db-uri", help="an existing database (SQLAlchemy URI, e.g. "
                              "postgresql+psycopg://user@host:5432/mlflow); default: a local cluster in <dir>/postgres")
    start_parser.add_argument("--host", default="127.0.0.1", help="loopback address to serve on")
    start_parser.add_argument("--port", type=int, default=5000, help="MLflow port")
    start_parser.add_argument("--pg-port", type=int, default=5433, help="port of the local PostgreSQL cluster")
    start_parser.add_argument("--timeout", type=float, default=120, help="seconds to wait for each server to answer")
    for name in ("stop", "status"):
        commands.add_parser(name)
    for sub in commands.choices.values():
        sub.add_argument("--dir", type=Path, default=runs_dir() / "server",
                         help="server folder: database cluster, artifacts, logs, server.json (default runs/server)")
    args = parser.parse_args(argv)
    try:
        if args.command == "start":
            state = start(args.dir, args.db_uri, args.host, args.port, args.pg_port, args.timeout)
            where = f"PostgreSQL {state['pg_data']} on 127.0.0.1:{state['pg_port']}" if state.get("pg_data") else \
                "the given database"
            print(f"MLflow serving {state['tracking_uri']} (pid {state['mlflow_pid']}) on {where}; "
                  f"artifacts in {args.dir.resolve() / 'artifacts'}")
            print(f"logger.tracking_uri={state['tracking_uri']}")
            return 0
        if args.command == "stop":
            print("\n".join(stop(args.dir)))
            return 0
        running, text = status(args.dir)
        print(text)
        return 0 if running else 3
    except (ServerError, subprocess.TimeoutExpired) as error:
        print(f"hrc-lab-server: {error}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
