"""``hrc-lab-runs``: look after the MLflow runs of a tracking store.

``hrc-lab-runs stale`` finds RUNNING runs whose process is gone (killed with SIGKILL, out of memory, a lost
node) and marks them KILLED, so nobody mistakes them for live jobs; reports never read them either way. A run is
stale when it was started on this host and its process (PID and start time, tags ``pid``/``process_start``) no
longer exists. Runs started on other hosts cannot be checked from here: they are listed, and marked only with
``--other-hosts-older-than HOURS``.

``hrc-lab-runs resumable`` lists the KILLED and FAILED runs of jobs not yet done: no run names them in
``resumed_from`` and no FINISHED or RUNNING run has the same config (the check ``resume_from`` makes). Each comes
with the command that continues it from its last checkpoint (``resume_from``, docs/interrupted.md).
"""

from __future__ import annotations

import argparse
import os
import socket
import tempfile
import time
from pathlib import Path

import yaml
from mlflow.entities import ViewType
from mlflow.tracking import MlflowClient

from hrc_lab.config import ConfigError, default_tracking_uri, validate_config
from hrc_lab.processes import process_start
from hrc_lab.tracking import changed_settings, compose_today, resolve_tracking_uri, schema_defaults_today


def runs_where(client: MlflowClient, query: str) -> list:
    experiments = client.search_experiments(view_type=ViewType.ALL)
    if not experiments:
        return []
    ids = [e.experiment_id for e in experiments]
    return client.search_runs(ids, query, max_results=50000)


def running_runs(client: MlflowClient) -> list:
    return runs_where(client, "attributes.status = 'RUNNING'")


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


def job_overrides(client: MlflowClient, run) -> list[str]:
    """The overrides of ``run``'s job (its ``hydra/overrides.yaml``), ``resume_from`` left out."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(client.download_artifacts(run.info.run_id, "hydra/overrides.yaml", tmp))
        overrides = yaml.safe_load(path.read_text())
    return [o for o in overrides if not o.startswith("resume_from=")]


def why_not_resumable(overrides: list[str]) -> str | None:
    """Why ``hrc-lab <overrides>`` (with its ``resume_from``) would fail its resume check today (e.g. the run's
    config is from before keys that exist now), or None when it would pass."""
    from hrc_lab.cli import check_resumable

    try:
        cfg = compose_today(tuple(overrides))
        check_resumable(validate_config(cfg), cfg)
    except ConfigError as err:
        return str(err).splitlines()[0]
    return None


def job_of(run) -> dict[str, str]:
    """What makes two runs the same job: their resolved config (params), ``resume_from`` aside."""
    return {key: value for key, value in run.data.params.items() if key != "resume_from"}


def same_job(ended, others: list, overrides: list[str]) -> list:
    """The runs of ``others`` that do ``ended``'s job: no setting either logged differs, and each key ``ended`` did
    not log (added since it ran) holds, in the other run, the schema default ``ended`` ran with
    (:func:`~hrc_lab.tracking.changed_settings`, the defaults of its job's ``overrides``, its task overrides). So a
    run that sets a key added since ``ended`` ran away from its default does another job. Where the runs log and
    write (the neutral groups) is not the job."""
    defaults = schema_defaults_today(tuple(overrides)) if others else {}
    return [other for other in others if not changed_settings(job_of(ended), job_of(other), defaults)]


def resumable(tracking_uri: str) -> list[tuple[str, str]]:
    """(run id, command) of every KILLED or FAILED job run that no run resumed, of a job (config) no FINISHED or
    RUNNING run did or does (:func:`same_job`), not tagged ``invalidated`` and that today's config can resume,
    oldest first. Each is printed with its command; a run today's config cannot resume, an invalidated one, or one
    whose job a RUNNING run does now, is printed with the reason."""
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")
    client = MlflowClient(resolve_tracking_uri(tracking_uri))
    ended = [run for status in ("KILLED", "FAILED") for run in runs_where(client, f"attributes.status = '{status}'")]
    finished = runs_where(client, "attributes.status = 'FINISHED'")
    running = running_runs(client)
    resumed = {run.data.tags.get("resumed_from") for run in [*ended, *finished, *running]}
    found = []
    for run in sorted(ended, key=lambda run: run.info.start_time):
        if "experiment" not in run.data.tags or run.data.tags.get("kind") == "summary":
            continue  # not a job's run
        if run.info.run_id in resumed:
            continue
        task = job_overrides(client, run)
        if same_job(run, finished, task):
            continue
        twin = next(iter(same_job(run, running, task)), None)
        if twin is not None:  # started afresh, not resumed: nothing to do unless that run ends unfinished too
            print(f"{run.info.status.lower():7}  {run.info.run_name}: its job is running now (run "
                  f"{twin.info.run_id}; if its process is gone, `hrc-lab-runs stale` first)")
            continue
        if "invalidated" in run.data.tags:
            print(f"{run.info.status.lower():7}  {run.info.run_name}: invalidated ({run.data.tags['invalidated']})")
            continue
        overrides = [*task, f"resume_from={run.info.run_id}"]
        reason = why_not_resumable(overrides)
        if reason is not None:
            print(f"{run.info.status.lower():7}  {run.info.run_name}: cannot resume today ({reason})")
            continue
        command = " ".join(["hrc-lab", "hydra.mode=RUN", *overrides])
        found.append((run.info.run_id, command))
        print(f"{run.info.status.lower():7}  {run.info.run_name}\n  {command}")
    return found


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="hrc-lab-runs", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    uri_help = "MLflow tracking URI (default: the store under $HRC_LAB_RUNS, else runs/)"
    parser.add_argument("--tracking-uri", default=default_tracking_uri(), help=uri_help)
    # the same option after the subcommand, where a user types it (`hrc-lab-runs stale --tracking-uri URL`)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--tracking-uri", default=argparse.SUPPRESS, help=uri_help)
    commands = parser.add_subparsers(dest="command", required=True)
    stale_cmd = commands.add_parser("stale", parents=[common], help="mark RUNNING runs whose process is gone KILLED")
    stale_cmd.add_argument("--dry-run", action="store_true", help="only list them")
    stale_cmd.add_argument("--other-hosts-older-than", type=float, default=None, metavar="HOURS",
                           help="also mark runs of other hosts started more than HOURS ago")
    commands.add_parser("resumable", parents=[common],
                        help="list the killed or failed runs left to resume, with the commands")
    args = parser.parse_args(argv)
    if args.command == "resumable":
        print(f"{len(resumable(args.tracking_uri))} run(s) to resume")
        return
    found = stale(args.tracking_uri, args.dry_run, args.other_hosts_older_than)
    print(f"{len(found)} stale run(s){' (dry run)' if args.dry_run else ''}")


if __name__ == "__main__":
    main()
