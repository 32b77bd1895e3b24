"""Building a report from its plan: ``reports/<topic>.md`` opens with the thesis' tables (thesis | as written | ★),
then one section per study of the plan (:mod:`hrc_lab.report.plans`), each from the finished runs of that study's
variant in one store; ``reports/README.md``, the scoreboard, gathers every report's thesis rows."""

from __future__ import annotations

import shutil
from datetime import UTC, datetime
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from mlflow.tracking import MlflowClient

from hrc_lab.report.headline import ROWS_FILE, TABLES_FILE, opening_tables, thesis_rows, write_scoreboard
from hrc_lab.report.plan import Plan, Study
from hrc_lab.report.plans import PLANS, plan_of
from hrc_lab.report.runs import finished_runs, newest_runs, sweeps_line, variants_of
from hrc_lab.report.sections import SECTIONS, Section, load_sections
from hrc_lab.report.times import PLAN_FILE, study_record, write_plan_times
from hrc_lab.tracking import resolve_tracking_uri


def section_of(runs: pd.DataFrame, table: str, study: Study | None = None) -> Section:
    """The section of ``table`` built from ``runs`` (the runs of one variant), naming the sweeps it read; a study
    with overrides has its own title."""
    load_sections()
    section = SECTIONS[table](runs)
    section.sources = sweeps_line(runs)
    if study is not None and study.title:
        section.title = study.title
    return section


def sections_from(runs: pd.DataFrame, table: str) -> list[tuple[str, str, Section]]:
    """(variant, its overrides, section) for each variant among ``runs`` (default first): a sweep's own summary
    (:class:`hrc_lab.report.callbacks.SweepSummary`), which may hold an ablation the plan does not."""
    if runs.empty:
        return []
    return [(name, overrides, section_of(runs[runs["variant"] == name], table))
            for name, overrides in variants_of(runs).items()]


def write_section(section: Section, folder: Path, tracking_uri: str, stem: str, command: str, key: str = "",
                  question: str = "") -> str:
    """Save the section's table (``<stem>.csv``), figures and copied artifacts under ``folder``; return its markdown:
    heading (with the anchor ``key``), Reproduce line, runs, the question an ablation answers, text, images."""
    folder.mkdir(parents=True, exist_ok=True)
    section.table.to_csv(folder / f"{stem}.csv", index=False)
    images = []
    for name, figure in section.figures.items():
        figure.savefig(folder / name, dpi=110)
        plt.close(figure)
        images.append(name)
    files = []
    client = MlflowClient(resolve_tracking_uri(tracking_uri))
    for name, (run_id, artifact) in section.artifacts.items():
        shutil.copy(client.download_artifacts(run_id, artifact), folder / name)
        (images if name.endswith((".png", ".jpg")) else files).append(name)
    lines = [f'<a id="{key}"></a>'] if key else []
    lines += [f"## {section.title}", "", f"Reproduce: `{command}`", ""]
    if section.sources:
        lines += [section.sources, ""]
    if question:
        lines += [f"**Question.** {question}", ""]
    lines += [section.markdown.strip(), ""]
    lines += [f"![{name}]({folder.name}/{name})" for name in images]
    lines += [f"[{name}]({folder.name}/{name})" for name in files]
    return "\n".join(lines).strip("\n") + "\n"


def study_runs(every: dict[str, pd.DataFrame], study: Study) -> pd.DataFrame:
    """The newest finished run of every job of ``study`` (its experiment's runs of its variant)."""
    return newest_runs(every[study.mlflow_experiment], variant=study.variant)


def header(plan: Plan, tracking_uri: str, runs: list[pd.DataFrame], missing: list[Study]) -> list[str]:
    """Which plan, store, commit(s), dates, wall time and CPU kernels the report was built from."""
    frame = pd.concat([r for r in runs if not r.empty], ignore_index=True) if any(not r.empty for r in runs) else None
    built = datetime.now(UTC).strftime("%Y-%m-%d")
    line = (f"Built by `hrc-lab-report {plan.topic}` on {built} from the store `{tracking_uri}`: the plan "
            f"`hrc-lab-reproduce {plan.topic}` ({len(plan.studies)} stud{'ies' if len(plan.studies) != 1 else 'y'}")
    line += f"; not run yet: {', '.join(s.key for s in missing)})." if missing else ")."
    lines = [line]
    if frame is None:
        lines.append("Runs: none finished in this store yet.")
    else:
        commits = frame.get("commit", pd.Series(["unknown"] * len(frame))).fillna("unknown")
        dirty = frame.get("commit_dirty", pd.Series(["unknown"] * len(frame))).fillna("unknown")
        shown = ", ".join(f"`{c[:10]}`" + (" (edited)" if (dirty[commits == c] == "true").any() else "")
                          for c in sorted(set(commits)))
        start = pd.to_datetime(frame["start_time"], unit="ms", utc=True)
        end = pd.to_datetime(frame["end_time"], unit="ms", utc=True) if "end_time" in frame else start
        kernels = ", ".join(sorted(set(frame.get("cpu_kernels", pd.Series(["not logged"])).fillna("not logged"))))
        cpus = ", ".join(sorted(set(frame.get("cpu", pd.Series(["not logged"])).fillna("not logged"))))
        lines.append(f"Runs: {len(frame)} finished, at commit {shown}, {start.min():%Y-%m-%d %H:%M} to "
                     f"{end.max():%Y-%m-%d %H:%M} UTC; the sweeps' wall time {sweep_hours(frame):.1f} h on {cpus} "
                     f"({frame['cpu_cores'].iloc[0] if 'cpu_cores' in frame else '?'} cores), CPU kernels {kernels}.")
    return lines


def sweep_hours(frame: pd.DataFrame) -> float:
    """Wall time of the sweeps that made ``frame``'s runs: per sweep, its last run's end minus its first run's
    start (a single run: its own duration), summed."""
    if "end_time" not in frame:
        return float("nan")
    seconds = 0.0
    for _, part in frame.groupby(frame["sweep"].where(frame["sweep"] != "none", frame["run_id"])):
        seconds += (part["end_time"].max() - part["start_time"].min()) / 1000
    return seconds / 3600


def build_topic(topic: str, tracking_uri: str, out_dir: Path) -> Path:
    """Write ``<out_dir>/<topic>.md``, its tables, plots and thesis rows from the runs of its plan's studies in the
    store at ``tracking_uri``, then the scoreboard ``<out_dir>/README.md`` from every report's thesis rows there and
    ``<out_dir>/plans.md`` (:mod:`hrc_lab.report.times`) from every report's study costs."""
    if topic not in PLANS:
        raise SystemExit(f"hrc-lab-report: unknown report '{topic}'; choose one of {sorted(PLANS)}")
    return build_report(plan_of(topic), tracking_uri, out_dir)


def build_report(plan: Plan, tracking_uri: str, out_dir: Path) -> Path:
    """:func:`build_topic` for a plan given whole (a test's one-study plan, a user's own)."""
    plan.check()
    topic = plan.topic
    every = {experiment: finished_runs(tracking_uri, experiment)
             for experiment in dict.fromkeys(study.mlflow_experiment for study in plan.studies)}
    folder = out_dir / topic
    if folder.is_dir():
        shutil.rmtree(folder)  # files of studies that no longer exist go with them
    parts, results, runs_read, missing = [], {}, [], []
    costs = []
    for study in plan.studies:
        runs = study_runs(every, study)
        runs_read.append(runs)
        costs.append(study_record(plan, study, runs, sweep_hours(runs) if not runs.empty else float("nan")))
        if runs.empty:
            missing.append(study)
            title = study.title or study.table
            parts.append(f'<a id="{study.key}"></a>\n## {title}\n\nNot run yet: `{study.command}`\n')
            continue
        section = section_of(runs, study.table, study)
        results[study.key] = section.results
        parts.append(write_section(section, folder, tracking_uri, study.key, study.command, study.key, study.question))
    rows = thesis_rows(plan, results)
    folder.mkdir(parents=True, exist_ok=True)
    rows.to_csv(folder / ROWS_FILE, index=False)
    pd.DataFrame(costs).to_csv(folder / PLAN_FILE, index=False)
    (folder / TABLES_FILE).write_text("\n".join(opening_tables(plan, rows, links=False)))
    opening = opening_tables(plan, rows)
    body = [f"# {plan.title}", "", *header(plan, tracking_uri, runs_read, missing), "",
            f"{plan.note.strip()} Thesis values: Ma (2024), `hrc_lab/reference/thesis_results.yaml`.", "",
            *(["## The thesis' results beside ours", "", *opening] if opening else []), *parts]
    path = out_dir / f"{topic}.md"
    path.write_text("\n".join(body).rstrip("\n") + "\n")
    write_scoreboard(out_dir)
    write_plan_times(out_dir)
    return path

