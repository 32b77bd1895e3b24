"""Concurrent writers on the two tracking stores: N = 2, 4, 8 parallel tiny jobs (Hydra joblib launcher,
``hydra.launcher.n_jobs=N``) each logging metrics every step, against (a) the sqlite store under runs/ and (b) the
team server (``hrc-lab-server``, MLflow on PostgreSQL). Prints a markdown table: lost runs (not FINISHED with every
step's metrics), failed writes, "database is locked" errors, sweep wall time.

    .venv/bin/python scripts/bench_tracking.py [--n 2 4 8] [--steps 200] [--dir runs/bench]
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

from mlflow.tracking import MlflowClient

from hrc_lab import server

JOB = Path(__file__).with_name("bench_tracking_job.py")


def sweep(uri: str, n: int, steps: int, metrics: int, work: Path) -> dict:
    bench = uuid.uuid4().hex[:8]
    results = work / f"results-{bench}"
    results.mkdir(parents=True)
    client = MlflowClient(uri)
    if client.get_experiment_by_name("bench") is None:  # as hrc-lab's sweep callback: the store exists before jobs
        client.create_experiment("bench")
    command = [sys.executable, str(JOB), "-m", f"job=range({n})", "hydra/launcher=joblib",
               f"hydra.launcher.n_jobs={n}", f"steps={steps}", f"metrics={metrics}", f"uri={uri}", f"bench={bench}",
               f"results={results}", f"hydra.sweep.dir={work / ('sweep-' + bench)}"]
    begin = time.monotonic()
    done = subprocess.run(command, capture_output=True, text=True, timeout=900)
    wall = time.monotonic() - begin
    jobs = [json.loads(p.read_text()) for p in results.glob("*.json")]
    errors = [e for job in jobs for e in job["errors"]]
    experiment = client.get_experiment_by_name("bench").experiment_id
    runs = client.search_runs([experiment], f"tags.bench = '{bench}'", max_results=1000)
    complete = [r for r in runs if r.info.status == "FINISHED"
                and len(client.get_metric_history(r.info.run_id, "m0")) == steps]
    locked = sum("database is locked" in e for e in errors) + done.stderr.count("database is locked")
    return {"n": n, "lost": n - len(complete), "failed_writes": len(errors), "locked": locked, "wall": wall,
            "job_seconds": max((j["seconds"] for j in jobs), default=float("nan")), "exit": done.returncode,
            "first_error": errors[0] if errors else (done.stderr.strip().splitlines() or [""])[-1][:200]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, nargs="+", default=[2, 4, 8])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--metrics", type=int, default=3)
    parser.add_argument("--dir", type=Path, default=Path(os.environ.get("HRC_LAB_RUNS", "runs")) / "bench")
    parser.add_argument("--port", type=int, default=5055)
    parser.add_argument("--pg-port", type=int, default=5455)
    args = parser.parse_args()
    work = args.dir.resolve()
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    rows = []
    for n in args.n:
        rows.append(("sqlite", sweep(f"sqlite:///{work / f'sqlite-{n}' / 'mlflow.db'}", n, args.steps, args.metrics,
                                     work / f"sqlite-{n}")))
        print(rows[-1], flush=True)
    state = server.start(work / "server", None, "127.0.0.1", args.port, args.pg_port, 120)
    try:
        for n in args.n:
            rows.append(("server", sweep(state["tracking_uri"], n, args.steps, args.metrics, work / f"server-{n}")))
            print(rows[-1], flush=True)
    finally:
        server.stop(work / "server")
    print(f"\n{args.steps} steps x {args.metrics} metrics per job, one log_batch per step; {os.cpu_count()} CPUs\n")
    print("| store | N jobs | lost runs | failed writes | \"database is locked\" | sweep wall (s) | slowest job (s) |")
    print("|:--|--:|--:|--:|--:|--:|--:|")
    for store, r in rows:
        print(f"| {store} | {r['n']} | {r['lost']} | {r['failed_writes']} | {r['locked']} | {r['wall']:.1f} "
              f"| {r['job_seconds']:.1f} |")
    for store, r in rows:
        if r["first_error"]:
            print(f"{store} N={r['n']}: {r['first_error']}")


if __name__ == "__main__":
    main()
