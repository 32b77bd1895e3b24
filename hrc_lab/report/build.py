"""Turning MLflow runs into report sections and files."""

from __future__ import annotations

import shutil
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from mlflow.tracking import MlflowClient

from hrc_lab.report.runs import (
    DEFAULT_VARIANT,
    fetch_runs,
    finished_runs,
    newest_runs,
    number_first,
    sweeps_line,
    variants_of,
)
from hrc_lab.report.sections import SECTIONS, TOPICS, Section, load_sections
from hrc_lab.run_naming import NEUTRAL_KEYS
from hrc_lab.tracking import resolve_tracking_uri

COMMANDS = {
    "table_3_1": "hrc-lab experiment=ch3/table_3_1 hydra/launcher=joblib",
    "fig_3_10": "hrc-lab experiment=ch3/fig_3_10 hydra/launcher=joblib",
    "fig_3_13": "hrc-lab experiment=ch3/fig_3_13 hydra/launcher=joblib",
    "fig_3_12": "hrc-lab experiment=ch3/fig_3_12 hydra/launcher=joblib",
    "fig_3_9": "hrc-lab experiment=ch3/fig_3_9 hydra/launcher=joblib",
    "fetch": "hrc-lab experiment=rl/fetch hydra/launcher=joblib",
    "table_4_1": "hrc-lab experiment=ch4/table_4_1 hydra/launcher=joblib",
    "fig_4_7": "hrc-lab experiment=ch4/fig_4_7 hydra/launcher=joblib",
    "practical": "hrc-lab experiment=ch4/practical hydra/launcher=joblib",
    "fig_4_9": "hrc-lab experiment=ch4/fig_4_9 hydra/launcher=joblib",
    "table_4_2": "hrc-lab experiment=ch4/table_4_2 hydra/launcher=joblib",
    "table_4_3": "hrc-lab experiment=ch4/table_4_3 hydra/launcher=joblib",
    "fig_5_7": "hrc-lab experiment=ch5/fig_5_7 hydra/launcher=joblib",
    "table_5_2_planner": "hrc-lab experiment=ch5/table_5_2_planner hydra/launcher=joblib",
    "fig_5_6": "hrc-lab experiment=ch5/fig_5_6 hydra/launcher=joblib",
    "table_5_2": "hrc-lab experiment=ch5/table_5_2 hydra/launcher=joblib",
    "hrc_session": "hrc-lab experiment=ch5/hrc_session hydra/launcher=joblib",
    "table_6_1": "hrc-lab experiment=ch6/table_6_1 hydra/launcher=joblib",
    "table_6_2_single": "hrc-lab experiment=ch6/table_6_2_single hydra/launcher=joblib",
    "table_6_2_robot": "hrc-lab experiment=ch6/table_6_2_robot hydra/launcher=joblib",
    "table_6_3": "hrc-lab experiment=ch6/table_6_3 hydra/launcher=joblib",
    "fig_6_9": "hrc-lab experiment=ch6/fig_6_9 hydra/launcher=joblib",
    "collect_ch4": "hrc-lab experiment=data/collect_ch4 hydra/launcher=joblib",
    "collect_ch3": "hrc-lab experiment=data/collect_ch3 hydra/launcher=joblib",
}


ABLATION_MARK = " — ablation: "  # in an ablation section's title, after the table's own title


def previous_sections(markdown: str, parts: list[tuple[str, str]]) -> dict[str, list[tuple[str, str]]]:
    """The sections of a report written by :func:`build_topic`, per table: (heading line, text from its heading to
    the next section's), in their order; a table's "No finished default runs" note is none. A section's table is
    the one whose command its "Reproduce:" line (two lines below the heading) runs; reports written before that
    line moved into its section (it stood two lines above the heading) are read too, and returned in today's
    layout."""
    lines = markdown.splitlines()
    commands = {COMMANDS.get(table, experiment): table for experiment, table in parts}

    def table_of(line: str) -> str | None:
        command = line.removeprefix("Reproduce: `").split("`", 1)[0]
        return next((t for c, t in commands.items() if command == c or command.startswith(c + " ")), None)

    starts = []  # (first line, heading line, table) of each section
    for i, line in enumerate(lines):
        if not line.startswith("## "):
            continue
        below = lines[i + 2] if i + 2 < len(lines) else ""
        if below.startswith("Reproduce: `"):
            starts.append((i, i, table_of(below)))
        elif i >= 2 and lines[i - 2].startswith("Reproduce: `"):  # the earlier layout
            starts.append((i - 2, i, table_of(lines[i - 2])))
        elif below.startswith("No finished default runs"):
            starts.append((i, i, None))
    sections: dict[str, list[tuple[str, str]]] = {}
    for (start, heading, table), (end, _, _) in zip(starts, [*starts[1:], (len(lines), 0, None)], strict=True):
        if table is None:
            continue
        body = lines[start:end]
        if start != heading:  # Reproduce, blank, heading -> heading, blank, Reproduce
            body[0], body[2] = body[2], body[0]
        sections.setdefault(table, []).append((lines[heading], "\n".join(body).rstrip("\n") + "\n"))
    return sections


def section_of(runs: pd.DataFrame, table: str) -> Section:
    """The section of ``table`` built from ``runs`` (runs of one variant), naming the sweeps it read. An ablation
    variant's section is titled "<title> — ablation: <overrides>" and its files carry the variant id, so that it
    never overwrites the default section's."""
    load_sections()
    section = SECTIONS[table](runs)
    section.sources = sweeps_line(runs)
    variant, overrides = next(iter(variants_of(runs).items()))
    if variant != DEFAULT_VARIANT:
        section.title = f"{section.title}{ABLATION_MARK}{overrides or variant}"
        section.figures = {_tagged(name, variant): figure for name, figure in section.figures.items()}
        section.artifacts = {_tagged(name, variant): source for name, source in section.artifacts.items()}
    return section


def _tagged(name: str, variant: str) -> str:
    path = Path(name)
    return f"{path.stem}_{variant}{path.suffix}"


def build_sections(
    tracking_uri: str, experiment: str, table: str, sweep: str | None = None, variant: str | None = DEFAULT_VARIANT
) -> list[tuple[str, str, Section]]:
    """(variant, the arguments that re-run it, section) for each variant of the finished runs read (one unless
    ``variant`` is None: then every variant present, default first), each built from its own runs only."""
    return sections_from(fetch_runs(tracking_uri, experiment, sweep, variant), table)


def sections_from(runs: pd.DataFrame, table: str) -> list[tuple[str, str, Section]]:
    """:func:`build_sections` for runs already fetched."""
    if runs.empty:
        return []
    return [(name, rerun_arguments(runs[runs["variant"] == name], overrides),
             section_of(runs[runs["variant"] == name], table))
            for name, overrides in variants_of(runs).items()]


def moved_headings(runs: pd.DataFrame, sections: list[tuple[str, str, Section]]) -> set[str]:
    """The headings that ``runs`` (:func:`~hrc_lab.report.runs.finished_runs`, older ones included) had before
    :mod:`hrc_lab.report.defaults` moved them to another variant: a previous report's section under such a heading
    is these runs' old section (e.g. one whose overrides are today's defaults), not one to keep."""
    if not sections or "logged_variant_overrides" not in runs:
        return set()
    title = sections[0][2].title.split(ABLATION_MARK)[0]
    moved = runs.loc[runs["variant_overrides"] != runs["logged_variant_overrides"], "logged_variant_overrides"]
    return {f"## {title}{ABLATION_MARK}{overrides}" if overrides else f"## {title}" for overrides in set(moved)}


def rerun_arguments(runs: pd.DataFrame, overrides: str) -> str:
    """The arguments to add to the table's command to re-run exactly ``runs`` of an ablation: the values each sweep
    key took in them (an ablation often covers a few cells or seeds, e.g. ``env=a,b seed=0,1,2``), read from the
    jobs' ``overrides`` tags, then the variant's own ``overrides``. "" for the default variant."""
    if not overrides or "overrides" not in runs:
        return overrides
    own = {item.split("=", 1)[0] for item in overrides.split()}
    values: dict[str, list[str]] = {}
    for job in runs["overrides"].dropna():
        for item in str(job).split():
            key, _, value = item.partition("=")
            if key in own or key.lstrip("+~").split(".")[0] in NEUTRAL_KEYS or not value:
                continue
            if value not in values.setdefault(key, []):
                values[key].append(value)
    swept = [f"{key}={','.join(sorted(found, key=number_first))}" for key, found in values.items()]
    return " ".join([*swept, overrides])


def write_section(section: Section, folder: Path, tracking_uri: str, stem: str, command: str | None = None) -> str:
    """Save the section's table, figures and copied artifacts under ``folder``; return its markdown with images,
    the ``command`` that re-runs it (if given) under its heading."""
    folder.mkdir(parents=True, exist_ok=True)
    section.table.to_csv(folder / f"{stem}.csv", index=False)
    images = []
    for name, figure in section.figures.items():
        figure.savefig(folder / name, dpi=120)
        plt.close(figure)
        images.append(name)
    client = MlflowClient(resolve_tracking_uri(tracking_uri))
    files = []
    for name, (run_id, artifact) in section.artifacts.items():
        shutil.copy(client.download_artifacts(run_id, artifact), folder / name)
        (images if name.endswith((".png", ".jpg")) else files).append(name)
    links = "\n".join(f"![{name}]({folder.name}/{name})" for name in images)
    links += "".join(f"\n\n[{name}]({folder.name}/{name})" for name in files)
    sources = f"{section.sources}\n\n" if section.sources else ""
    reproduce = f"Reproduce: `{command}`\n\n" if command else ""
    return f"## {section.title}\n\n{reproduce}{sources}{section.markdown}\n\n{links}\n"


def build_topic(topic: str, tracking_uri: str, out_dir: Path, sweep: str | None = None,
                update: bool = False) -> Path:
    """Write ``<out_dir>/<topic>.md`` and its PNGs from the newest default run of every (scenario, cell, method,
    seed), optionally of one sweep only; each ablation variant present follows its table in its own section.

    ``update``: keep each section of the existing ``<out_dir>/<topic>.md`` that this store (or sweep) has no runs
    for, as it is (it names the sweeps it was built from), and rebuild the others: for a store that holds only
    some of a report's runs, e.g. one figure re-run on a new machine."""
    if topic not in TOPICS:
        raise SystemExit(f"hrc-lab-report: unknown report '{topic}'; choose one of {sorted(TOPICS)}")
    title, data_note, parts = TOPICS[topic]
    path = out_dir / f"{topic}.md"
    previous = previous_sections(path.read_text(), parts) if update and path.is_file() else {}
    scope = (f" --sweep {sweep}" if sweep else "") + (" --update" if update else "")
    kept_note = (" Sections whose runs were not in that store are kept from the report as it was, each naming the "
                 "sweeps it was built from." if update else "")
    body = [
        f"# {title}",
        "",
        f"Generated by `hrc-lab-report {topic}{scope}` from the MLflow runs in `{tracking_uri}`; every number below "
        "is computed by the runs named in its section (re-run the command, then this report). Sections read the "
        "default runs (the experiment as configured); a run with any other override is an ablation with its own "
        f"section.{kept_note} Thesis values: Ma (2024), "
        f"copied in `hrc_lab/reference/thesis_results.yaml`. {data_note}",
        "",
    ]
    for experiment, table in parts:
        every = finished_runs(tracking_uri, experiment, sweep)
        sections = sections_from(newest_runs(every, variant=None), table)
        command = COMMANDS.get(table, experiment)
        built = {f"## {section.title}" for _, _, section in sections} | moved_headings(every, sections)
        kept = [(heading, text) for heading, text in previous.get(table, []) if heading not in built]
        has_default = DEFAULT_VARIANT in {variant for variant, _, _ in sections}
        if not has_default and kept and ABLATION_MARK not in kept[0][0]:
            body.append(kept.pop(0)[1])  # the previous default section, its runs not in this store
        elif not has_default:
            missing = f"in sweep {sweep}." if sweep else f"yet: `{command}`."
            body.append(f"## {table}\n\nNo finished default runs {missing}\n")
        for variant, overrides, section in sections:  # default first, then each ablation in its own section
            ablation = variant != DEFAULT_VARIANT
            stem = f"{table}_{variant}" if ablation else table
            rerun = f"{command}{' ' + overrides if ablation and overrides else ''}"
            body.append(write_section(section, out_dir / topic, tracking_uri, stem, rerun))
        body.extend(text for heading, text in kept if ABLATION_MARK in heading)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(body))
    return path
