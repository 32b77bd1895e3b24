"""``hrc-lab-reproduce all`` (or ``ch3``, ``ch4``, ``ch5``, ``ch6``, ``data``, or one report such as
``ch5_perception``): run every study of the chosen chapters' plans, then build their reports, and print each step's
wall time.

The plan is :mod:`hrc_lab.report.plans`: each report's studies, each one sweep (the Reproduce line its section
prints), plus the steps a report links but no table reads (the rendered demonstration videos). Each step is a
subprocess of the installed console scripts beside ``sys.executable``; the run stops at the first failing step,
naming it. A report is rebuilt whole from its plan's runs in the store (``hrc-lab-report <topic>``): nothing is kept
from an earlier report. Finished sweeps are journaled (``<runs>/reproduce.jsonl``); ``--resume`` skips those of the
same command, store and machine and counts their recorded wall times in the total.

``--check`` builds the fresh reports into a temporary folder instead of ``reports/`` and compares their CSV tables
with the committed ones: a ``<x>_mean`` / ``mean`` cell differs when |fresh − committed| exceeds the larger of the
two ``std`` cells beside it (its seed spread); a cell without a spread must match exactly."""

from __future__ import annotations

import argparse
import json
import math
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from hrc_lab.config import runs_dir
from hrc_lab.console import quiet_third_party
from hrc_lab.processes import code_identity, machine_identity, signal_group

CHAPTERS = ("ch3", "ch4", "ch5", "ch6", "data")

# Experiment files under conf/experiment that are no study of a plan, with the reason they are not run.
LEFT_OUT = {
    "ch4/table_4_1_quick": "a few-minute preview of ch4/table_4_1 (README command 1); its runs are kept apart",
    "data/collect": "one demonstration set chosen on the command line; collect_ch3 / collect_ch4 run every set",
    "ch5/annotate": "annotates a video given on the command line; reuses the detector cached by ch5/table_5_2",
}

# Sweeps that copy a file into reports/ themselves; with --check the copy goes to the fresh reports' folder instead
# (the report links it relative to itself), so a check never rewrites committed files.
PUBLISHES = {"experiment=data/render_demo": "protocol.publish_dir={out}/videos"}

# Report columns that are wall-clock speeds of the machine that ran them, not results: never compared.
MACHINE_DEPENDENT = {"latency_ms", "env steps/s", "demos/min"}


@dataclass(frozen=True)
class Step:
    name: str  # "sweep ch4/table_4_1", "report ch4_reasoning"
    kind: str  # "sweep" or "report"
    topic: str
    argv: tuple[str, ...]  # argv[0]: "hrc-lab", "hrc-lab-report" (console scripts beside sys.executable) or "python"


def chapter_of(topic: str) -> str:
    return topic.split("_", 1)[0]


def _sweep(topic: str, args: tuple[str, ...], name: str) -> Step:
    return Step(f"sweep {name}", "sweep", topic, ("hrc-lab", *args))


def build_plan() -> list[Step]:
    """Every study of every plan (chapter order, then the plan's order), then every report."""
    from hrc_lab.report.plans import PLANS

    topics = sorted(PLANS, key=lambda topic: CHAPTERS.index(chapter_of(topic)))
    sweeps, reports = [], []
    for topic in topics:
        plan = PLANS[topic]
        for study in plan.studies:
            for argv in study.sweeps:
                shown = " ".join(arg.removeprefix("experiment=") for arg in argv if arg != study.launcher)
                sweeps.append(_sweep(topic, argv, f"{shown} [{study.key}]" if study.overrides else shown))
        for args in plan.extra:
            shown = " ".join(arg.removeprefix("experiment=") for arg in args)
            sweeps.append(_sweep(topic, args, shown))
        reports.append(Step(f"report {topic}", "report", topic, ("hrc-lab-report", topic)))
    return sweeps + reports


def __getattr__(name: str):
    """``PLAN``: :func:`build_plan`, built on first use (importing the plans imports every report module, after the
    console script has quieted the libraries' warnings)."""
    if name == "PLAN":
        globals()["PLAN"] = build_plan()
        return globals()["PLAN"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def select(plan: list[Step], selections: list[str]) -> list[Step]:
    """The steps of the chosen chapters or topics ("all": every step), in plan order."""
    if "all" in selections:
        return list(plan)
    return [step for step in plan if step.topic in selections or chapter_of(step.topic) in selections]


def command_of(step: Step, tracking_uri: str | None, out: Path | None) -> list[str]:
    head, *rest = step.argv
    bin_dir = Path(sys.executable).parent
    argv = [sys.executable if head == "python" else str(bin_dir / head), *rest]
    if step.kind == "sweep" and tracking_uri:
        argv.append(f"logger.tracking_uri={tracking_uri}")
    if step.kind == "sweep" and out:
        argv += [override.format(out=out) for arg, override in PUBLISHES.items() if arg in step.argv]
    if step.kind == "report":
        argv += ["--tracking-uri", tracking_uri] if tracking_uri else []
        argv += ["--out", str(out)] if out else []
    return argv


def _display(argv: list[str]) -> str:
    bin_dir = str(Path(sys.executable).parent) + "/"
    return shlex.join([arg.removeprefix(bin_dir) if i == 0 else arg for i, arg in enumerate(argv)])


def _duration(seconds: float) -> str:
    minutes, secs = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}"


def print_summary(rows: list[tuple[str, float | None, str]], machine: dict[str, str]) -> None:
    """Each step's wall time and status, the total, and the machine they were measured on."""
    width = max([len("step")] + [len(name) for name, _, _ in rows])
    print(f"\nmachine: {machine['cpu']}, {machine['cpu_cores']} cores, torch kernels {machine['cpu_capability']} "
          f"({machine['cpu_kernels']})")
    print(f"{'step':<{width}}  {'wall':>9}  status")
    for name, seconds, status in rows:
        print(f"{name:<{width}}  {_duration(seconds) if seconds is not None else '-':>9}  {status}")
    total = sum(seconds for _, seconds, _ in rows if seconds is not None)
    print(f"{'total':<{width}}  {_duration(total):>9}")


# ---- the journal: finished sweeps, so that --resume continues a reproduction that was stopped ----

JOURNAL = "reproduce.jsonl"  # under the runs folder (hrc_lab.config.runs_dir)


def journal_path() -> Path:
    return runs_dir() / JOURNAL


def _journal_key(command: str, tracking_uri: str | None, machine: dict[str, str]) -> tuple[str, str, str, str]:
    """A sweep counts as done for the same command, store and machine (a time measured elsewhere is not this
    machine's)."""
    return command, tracking_uri or "", machine["cpu"], machine["cpu_cores"]


def read_journal(path: Path) -> dict[tuple[str, str, str, str], dict]:
    """The newest entry per key of the journal at ``path`` (empty when there is none)."""
    entries: dict[tuple[str, str, str, str], dict] = {}
    if path.is_file():
        for line in path.read_text().splitlines():
            entry = json.loads(line)
            entries[_journal_key(entry["command"], entry["tracking_uri"], entry)] = entry
    return entries


def record(path: Path, command: str, tracking_uri: str | None, seconds: float, machine: dict[str, str]) -> None:
    """Append a finished sweep to the journal."""
    path.parent.mkdir(parents=True, exist_ok=True)
    entry = {"command": command, "tracking_uri": tracking_uri or "", "seconds": round(seconds, 1),
             "finished": datetime.now(UTC).isoformat(timespec="seconds"),
             "cpu": machine["cpu"], "cpu_cores": machine["cpu_cores"], **code_identity()}
    with path.open("a") as file:
        file.write(json.dumps(entry) + "\n")


# After a stop signal has been forwarded: how long the step may take to mark its MLflow runs KILLED and exit before
# its process group is killed (SIGKILL).
STOP_GRACE_S = 30.0


class Stopped(Exception):
    """The reproduction was stopped by a signal (Ctrl-C, ``kill``, a cluster's time limit) during a step."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _run(argv: list[str]) -> int:
    """Run one step in its own process group and return its exit code. SIGINT / SIGTERM to this process reach the
    whole group (the sweep and its launcher's workers, which mark their MLflow runs KILLED); once the group has
    exited, or ``STOP_GRACE_S`` after the signal, whatever is left of it is killed (idle joblib workers would
    outlive their sweep) and :class:`Stopped` is raised."""
    child = subprocess.Popen(argv, start_new_session=True)
    received: list[int] = []

    def forward(signum, frame):
        received.append(signum)
        signal_group(child.pid, signum)

    previous = {sig: signal.signal(sig, forward) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        kill_at = math.inf
        while True:
            returncode = child.poll()
            if not received:
                if returncode is not None:
                    break
            elif kill_at == math.inf:
                kill_at = time.monotonic() + STOP_GRACE_S
            elif returncode is not None and not signal_group(child.pid, 0):
                break
            elif time.monotonic() > kill_at:
                signal_group(child.pid, signal.SIGKILL)
                if returncode is not None:
                    break
            time.sleep(0.2)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if received:
        raise Stopped(received[0])
    return returncode


def run_steps(steps: list[Step], tracking_uri: str | None, out: Path | None, resume: bool = False) -> int:
    """Run ``steps`` in order with their output streamed; stop at the first failure or at a stop signal, and print
    the summary either way. Every finished sweep is appended to the journal; with ``resume`` a sweep the journal
    holds (same command, store and machine) is not run again and its recorded wall time counts in the total.
    Returns the exit code (128 + the signal's number when stopped by one)."""
    journal, machine = journal_path(), machine_identity()
    done = read_journal(journal) if resume else {}
    rows: list[tuple[str, float | None, str]] = []
    code, problem = 0, ""
    for index, step in enumerate(steps):
        argv = command_of(step, tracking_uri, out)
        shown = _display(argv)
        earlier = done.get(_journal_key(shown, tracking_uri, machine)) if step.kind == "sweep" else None
        if earlier:
            print(f"\n==> [{index + 1}/{len(steps)}] {step.name}: done {earlier['finished']} (--resume)", flush=True)
            rows.append((step.name, earlier["seconds"], f"ok (earlier run, finished {earlier['finished']})"))
            continue
        print(f"\n==> [{index + 1}/{len(steps)}] {step.name}: {shown}", flush=True)
        start = time.monotonic()
        try:
            returncode = _run(argv)
        except Stopped as stop:
            code, problem = 128 + stop.signum, f"stopped by {stop} during step '{step.name}'"
            rows.append((step.name, time.monotonic() - start, f"STOPPED ({stop})"))
        else:
            seconds = time.monotonic() - start
            if returncode == 0:
                if step.kind == "sweep":
                    record(journal, shown, tracking_uri, seconds, machine)
                rows.append((step.name, seconds, "ok"))
                continue
            code, problem = (returncode if returncode > 0 else 1), f"step '{step.name}' failed (exit {returncode})"
            rows.append((step.name, seconds, f"FAILED (exit {returncode})"))
        rows += [(later.name, None, "not run") for later in steps[index + 1 :]]
        break
    print_summary(rows, machine)
    if code:
        print(f"hrc-lab-reproduce: {problem}; later steps not run (--resume continues after the finished sweeps)",
              file=sys.stderr)
    return code


# ---- --check: fresh report tables against the committed ones ----

_PLUS_MINUS = re.compile(r"^\s*([-+0-9.eE]+|nan)\s*±\s*([-+0-9.eE]+|nan)\s*$")


def _number(value) -> float | None:
    """A cell as a float (NaN for an empty cell), or None when it is text."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _mean_std(value) -> tuple[float, float] | None:
    match = _PLUS_MINUS.match(str(value))
    return (float(match.group(1)), float(match.group(2))) if match else None


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def _spread_column(column: str, columns) -> str | None:
    """The std column beside a mean column: ``x_mean``/``x_std``, ``mean``/``std``, ``mean_m``/``std_m``."""
    if "mean" not in column:
        return None
    partner = column.replace("mean", "std")
    return partner if partner in columns else None


def _keyed(table: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Rows indexed by the table's text columns plus the occurrence number among equal keys."""
    frame = table.copy()
    group = frame.groupby(keys, dropna=False, sort=False).cumcount() if keys else pd.Series(range(len(frame)))
    frame["#"] = group.to_numpy()
    return frame.set_index([*keys, "#"])


def compare_tables(committed: pd.DataFrame, fresh: pd.DataFrame, label: str) -> list[str]:
    """Every cell of ``fresh`` that differs from ``committed`` by more than its seed spread (see module doc)."""
    if list(committed.columns) != list(fresh.columns):
        return [f"{label}: columns differ: committed {list(committed.columns)}, fresh {list(fresh.columns)}"]
    keys = [c for c in committed.columns if all(_number(v) is None or _mean_std(v) for v in committed[c])]
    keys = [c for c in keys if not any(_mean_std(v) for v in committed[c])]
    old, new = _keyed(committed, keys), _keyed(fresh, keys)
    differences = [f"{label}: row {key} only in the committed table" for key in old.index.difference(new.index)]
    differences += [f"{label}: row {key} only in the fresh table" for key in new.index.difference(old.index)]
    spreads = {c: _spread_column(c, committed.columns) for c in committed.columns}
    skipped = set(keys) | MACHINE_DEPENDENT | {s for s in spreads.values() if s}
    for key in old.index.intersection(new.index, sort=False):
        for column in committed.columns:
            if column in skipped:
                continue
            a, b = old.at[key, column], new.at[key, column]
            where = f"{label}: row {key}, {column}"
            pair_a, pair_b = _mean_std(a), _mean_std(b)
            if pair_a and pair_b:
                (mean_a, std_a), (mean_b, std_b) = pair_a, pair_b
            elif spreads[column]:
                mean_a, std_a = _number(a), _number(old.at[key, spreads[column]])
                mean_b, std_b = _number(b), _number(new.at[key, spreads[column]])
                if None in (mean_a, std_a, mean_b, std_b):
                    if str(a) != str(b):
                        differences.append(f"{where}: committed {a!r}, fresh {b!r}")
                    continue
            else:
                num_a, num_b = _number(a), _number(b)
                if num_a is None or num_b is None:
                    if str(a) != str(b):
                        differences.append(f"{where}: committed {a!r}, fresh {b!r}")
                elif not _same(num_a, num_b):
                    differences.append(f"{where}: committed {a}, fresh {b} (no spread: must match)")
                continue
            spread = max(std_a, std_b) if not (math.isnan(std_a) and math.isnan(std_b)) else 0.0
            spread = 0.0 if math.isnan(spread) else spread
            if math.isnan(mean_a) or math.isnan(mean_b):
                if not _same(mean_a, mean_b):
                    differences.append(f"{where}: committed {mean_a}, fresh {mean_b}")
            elif abs(mean_b - mean_a) > spread and not _same(mean_a, mean_b):
                differences.append(
                    f"{where}: committed {mean_a:.4g} ± {std_a:.2g}, fresh {mean_b:.4g} ± {std_b:.2g} "
                    f"(|Δ| {abs(mean_b - mean_a):.3g} > spread {spread:.3g})"
                )
    return differences


def compare_reports(committed: Path, fresh: Path, topics: list[str]) -> tuple[list[str], list[str]]:
    """(differences, notes) between ``<committed>/<topic>/*.csv`` and ``<fresh>/<topic>/*.csv``."""
    differences, notes = [], []
    for topic in topics:
        old_dir, new_dir = committed / topic, fresh / topic
        if not old_dir.is_dir():
            notes.append(f"{topic}: no committed tables under {old_dir}; nothing to compare")
            continue
        names = sorted({p.name for p in old_dir.glob("*.csv")} | {p.name for p in new_dir.glob("*.csv")})
        for name in names:
            label = f"{topic}/{name}"
            if not (new_dir / name).exists():
                differences.append(f"{label}: committed, but the fresh report has no such table")
            elif not (old_dir / name).exists():
                differences.append(f"{label}: in the fresh report, not committed")
            else:
                differences += compare_tables(pd.read_csv(old_dir / name), pd.read_csv(new_dir / name), label)
    return differences, notes


def check(committed: Path, fresh: Path, topics: list[str]) -> int:
    differences, notes = compare_reports(committed, fresh, topics)
    print(f"\n--check: fresh tables in {fresh} against the committed ones in {committed}")
    for note in notes:
        print(f"  note: {note}")
    for difference in differences:
        print(f"  DIFFERS {difference}")
    print(f"--check: {len(differences)} cell(s) or table(s) differ beyond their seed spread")
    return 1 if differences else 0


def main(argv: list[str] | None = None) -> int:
    from hrc_lab.report.plans import PLANS

    choices = ["all", *CHAPTERS, *sorted(PLANS)]
    parser = argparse.ArgumentParser(
        prog="hrc-lab-reproduce", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "selection", nargs="+", choices=choices, metavar="WHAT", help=f"what to reproduce: {', '.join(choices)}"
    )
    parser.add_argument("--dry-run", action="store_true", help="print the plan, run nothing")
    parser.add_argument(
        "--tracking-uri",
        default=None,
        help="MLflow tracking URI for every job (logger.tracking_uri=) and report (--tracking-uri)",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="build the reports into a temporary folder and compare their tables with the committed "
        "ones; exit 1 when a cell differs by more than its seed spread",
    )
    parser.add_argument(
        "--reports-only",
        action="store_true",
        help="skip the sweeps: build the reports from the runs already in the store",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help=f"skip the sweeps that finished in an earlier reproduction with the same command, store and machine "
        f"(the journal <runs>/{JOURNAL}); their recorded wall times count in the total",
    )
    parser.add_argument(
        "--committed", type=Path, default=Path("reports"), help="folder of the committed reports (default: reports)"
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="with --check: folder for the fresh reports (default: a new temporary one)",
    )
    args = parser.parse_args(argv)

    steps = select(sys.modules[__name__].PLAN, args.selection)
    if args.reports_only:
        steps = [step for step in steps if step.kind == "report"]
    out = None
    if args.check and not args.dry_run:
        out = args.out or Path(tempfile.mkdtemp(prefix="hrc-lab-reproduce-"))
    if args.dry_run:
        out = Path("<temporary folder>") if args.check else None
        for index, step in enumerate(steps):
            print(f"[{index + 1}/{len(steps)}] {step.name}: {_display(command_of(step, args.tracking_uri, out))}")
        return 0
    code = run_steps(steps, args.tracking_uri, out, resume=args.resume)
    if code or not args.check:
        return code
    return check(args.committed, out, sorted({step.topic for step in steps if step.kind == "report"}))


def console() -> None:
    quiet_third_party()
    sys.exit(main())


if __name__ == "__main__":
    console()
