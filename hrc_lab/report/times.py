"""What each plan cost: ``<reports>/<topic>/plan.csv`` (one row per study: its runs, the commit they ran at, the
sweep's wall time) written with each report, and ``<reports>/plans.md``, one table of every report built there, for
docs/reproduce.md to include (no links: the docs include it as it is)."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from hrc_lab.report.plan import Plan, Study

PLAN_FILE = "plan.csv"  # <reports>/<topic>/plan.csv
TIMES_FILE = "plans.md"  # <reports>/plans.md
COLUMNS = ["topic", "study", "title", "runs", "commit", "hours", "cpu"]


def study_record(plan: Plan, study: Study, runs: pd.DataFrame, hours: float) -> dict:
    """One row of ``plan.csv``: ``hours`` is the study's sweep wall time (NaN when it has not run)."""
    commits = sorted(set(runs["commit"].fillna("unknown"))) if "commit" in runs else []
    cpus = sorted(set(runs["cpu"].fillna("not logged"))) if "cpu" in runs else []
    return {"topic": plan.topic, "study": study.key, "title": study.title or study.table, "runs": len(runs),
            "commit": " ".join(c[:10] for c in commits), "hours": hours, "cpu": "; ".join(cpus)}


def write_plan_times(reports: Path) -> Path:
    """``<reports>/plans.md`` from every ``<topic>/plan.csv`` there: per report its studies run, runs, commit and
    the sweeps' wall time, their total, then per study."""
    files = sorted(reports.glob(f"*/{PLAN_FILE}"))
    studies = pd.concat([pd.read_csv(f, dtype={"commit": str}) for f in files], ignore_index=True) if files else \
        pd.DataFrame(columns=COLUMNS)
    lines = ["# What each plan took", "",
             "Generated with the reports (`hrc-lab-report <topic>` rewrites it from every report's "
             f"`<topic>/{PLAN_FILE}`): each study's sweep wall time, from its runs' start and end times in the store "
             "the report was built from (2 cores unless the CPU says otherwise).", ""]
    if studies.empty:
        (reports / TIMES_FILE).write_text("\n".join(lines + ["No report built yet."]) + "\n")
        return reports / TIMES_FILE
    studies["commit"] = studies["commit"].fillna("")
    table = ["| report | studies run | runs | at commit | wall time (h) |", "|---|---|---|---|---|"]
    for topic, part in studies.groupby("topic", sort=True):
        done = part[part["runs"] > 0]
        commits = ", ".join(sorted({c for cs in done["commit"] for c in cs.split()})) or "–"
        table.append(f"| {topic} | {len(done)} of {len(part)} | {int(part['runs'].sum())} | "
                     f"{commits} | {_hours(done['hours'].sum()) if len(done) else '–'} |")
    run = studies[studies["runs"] > 0]
    table.append(f"| all | {len(run)} of {len(studies)} | {int(studies['runs'].sum())} |  | "
                 f"{_hours(run['hours'].sum())} |")
    detail = ["| report | study | runs | wall time (min) |", "|---|---|---|---|"]
    for _, one in studies.iterrows():
        minutes = "not run yet" if one["runs"] == 0 else f"{one['hours'] * 60:.0f}"
        detail.append(f"| {one['topic']} | {one['study']} | {one['runs']} | "
                      f"{minutes} |")
    cpus = sorted({c for cs in run["cpu"].fillna("") for c in str(cs).split("; ") if c})
    lines += [*table, "", f"CPU: {', '.join(cpus) or 'not logged'}.", "", "Per study:", "", *detail]
    (reports / TIMES_FILE).write_text("\n".join(lines) + "\n")
    return reports / TIMES_FILE


def _hours(value: float) -> str:
    return "–" if value != value or math.isinf(value) else f"{value:.2f}"
