"""``hrc-lab-runs``: look after the MLflow runs of a tracking store.

``hrc-lab-runs stale`` finds RUNNING runs whose process is gone (killed with SIGKILL, out of memory, a lost
node) and marks them KILLED, so nobody mistakes them for live jobs; reports never read them either way. A run is
stale when it was started on this host and its process (PID and start time, tags ``pid``/``process_start``) no
longer exists. Runs started on other hosts cannot be checked from here: they are listed, and marked only with
``--other-hosts-older-than HOURS``.
"""

from __future__ import annotations

import argparse
import socket
import time

from mlflow.entities import ViewType
from mlflow.tracking import MlflowClient

from hrc_lab.config import default_tracking_uri
from hrc_lab.processes import process_start
from hrc_lab.tracking import resolve_tracking_uri


def running_runs(client: MlflowClient) -> list:
    experiments = client.search_experiments(view_type=ViewType.ALL)
    if not experiments:
        return []
    ids = [e.experiment_id for e in experiments]
    return client.search_runs(ids, "attributes.status = 'RUNNING'", max_results=50000)


def why_stale(run, host: str, now_ms: int, other_hosts_hours: float | None) -> str | None:
    """The reason ``run`` is stale, or None when it may still be running (or cannot be told from here)."""
    tags = run.data.tags
    if tags.get("host") == host and tags.get("pid"):
        started = process_start(int(tags["pid"]))
        if started is None:
            return f"process {tags['pid']} on {host} is gone"
        if started != tags.get("process_start"):
            return f"PID {tags['pid']} on {host} now belongs to another process"
        return None
    age_hours = (now_ms - run.info.start_time) / 3.6e6
    if other_hosts_hours is not None and age_hours > other_hosts_hours:
        return f"started {age_hours:.1f} h ago on {tags.get('host', 'an unknown host')}"
    return None


def stale(tracking_uri: str, dry_run: bool, other_hosts_hours: float | None) -> list[tuple[str, str]]:
    """Mark stale RUNNING runs KILLED (tag ``killed_by=hrc-lab-runs stale``); return (run id, reason) of each."""
    client = MlflowClient(resolve_tracking_uri(tracking_uri))
    host, now = socket.gethostname(), int(time.time() * 1000)
    found = []
    for run in running_runs(client):
        reason = why_stale(run, host, now, other_hosts_hours)
        name = run.info.run_name
        if reason is None:
            print(f"running  {run.info.run_id}  {name}  (host {run.data.tags.get('host', '?')})")
            continue
        found.append((run.info.run_id, reason))
        print(f"stale    {run.info.run_id}  {name}: {reason}{'' if dry_run else ' -> KILLED'}")
        if not dry_run:
            client.set_tag(run.info.run_id, "killed_by", "hrc-lab-runs stale")
            client.set_tag(run.info.run_id, "signal", "unknown (process gone)")
            client.set_terminated(run.info.run_id, "KILLED")
    return found


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="hrc-lab-runs", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tracking-uri", default=default_tracking_uri(),
                        help="MLflow tracking URI (default: the store under $HRC_LAB_RUNS, else runs/)")
    commands = parser.add_subparsers(dest="command", required=True)
    stale_cmd = commands.add_parser("stale", help="mark RUNNING runs whose process is gone KILLED")
    stale_cmd.add_argument("--dry-run", action="store_true", help="only list them")
    stale_cmd.add_argument("--other-hosts-older-than", type=float, default=None, metavar="HOURS",
                           help="also mark runs of other hosts started more than HOURS ago")
    args = parser.parse_args(argv)
    found = stale(args.tracking_uri, args.dry_run, args.other_hosts_older_than)
    print(f"{len(found)} stale run(s){' (dry run)' if args.dry_run else ''}")


if __name__ == "__main__":
    main()
