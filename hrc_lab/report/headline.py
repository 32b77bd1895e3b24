"""The thesis' rows beside ours: each report's opening tables and the scoreboard (``reports/README.md``).

A section builder returns, beside its table, ``Section.results``: one row per (method, thesis column) with ``mean``,
``std`` and ``n`` (seeds), or, for a figure's qualitative statement, ``text`` and ``met``. A plan's :class:`Row`
says which study and method stand for the thesis' method as written and for hrc_lab's ★ method; this module reads
the thesis' values, decides whether each is within the thesis' spread (or above), and lays the rows out.

Within the spread: for every column, ours ≥ thesis − tolerance (≤ thesis + tolerance where less is better), the
tolerance being the larger of the thesis' std, our std over seeds and 0.01 (the two decimals both print)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pandas as pd

from hrc_lab.report.plan import Pick, Plan, Row
from hrc_lab.report.thesis import thesis_fmt, thesis_row

RESULT_COLUMNS = ["row", "column", "mean", "std", "n", "text", "met"]
ROWS_FILE = "thesis_rows.csv"  # <reports>/<topic>/thesis_rows.csv, read by the scoreboard
FLOOR = 0.01


def results_frame(records: list[dict]) -> pd.DataFrame:
    """A section's ``results`` from records with (a subset of) :data:`RESULT_COLUMNS`."""
    return pd.DataFrame(records, columns=RESULT_COLUMNS)


def from_stats(stats: pd.DataFrame, row: str = "method", column: str = "cell") -> list[dict]:
    """Result records from a :func:`hrc_lab.report.runs.mean_std` frame (columns ``row``, ``column``, mean, std,
    n)."""
    return [{"row": r[row], "column": str(r[column]), "mean": r["mean"], "std": r["std"], "n": r["n"]}
            for _, r in stats.iterrows()]


def within(mean: float, std: float, n: int, thesis: float, thesis_std: float | None, higher: bool) -> bool:
    """Whether our mean over ``n`` seeds is within the thesis' spread of its value or above (below when lower is
    better): the tolerance is the larger of the thesis' std, the standard error of our mean (std / sqrt(n), so that
    3 seeds that scatter widely do not make any mean "within") and :data:`FLOOR`."""
    standard_error = 0.0 if std != std else std / math.sqrt(max(n, 1))
    tolerance = max(FLOOR, 0.0 if thesis_std is None else thesis_std, standard_error)
    return mean >= thesis - tolerance if higher else mean <= thesis + tolerance


def _ours(row: Row, pick: Pick | None, kind: str, results: dict[str, pd.DataFrame], columns: list[str],
          thesis: list) -> list[dict]:
    if pick is None:
        return []
    found = results.get(pick.study)
    found = found[found["row"] == pick.row] if found is not None and not found.empty else pd.DataFrame()
    records = []
    for column, (ref, ref_std) in zip(columns, thesis, strict=True):
        hit = found[found["column"].astype(str) == column] if not found.empty else found
        record = {"kind": kind, "label": pick.label, "column": column, "mean": math.nan, "std": math.nan, "n": 0,
                  "text": "", "met": None, "study": pick.study}
        if len(hit):
            value = hit.iloc[0]
            record.update(mean=value["mean"], std=value["std"], n=int(value["n"]) if value["n"] == value["n"] else 0,
                          text="" if pd.isna(value.get("text")) else str(value.get("text")))
            if row.claim:
                record["met"] = None if pd.isna(value.get("met")) else bool(value.get("met"))
            elif ref is not None and value["mean"] == value["mean"]:
                record["met"] = within(value["mean"], value["std"], record["n"], ref, ref_std,
                                       row.higher and column not in row.lower)
        records.append(record)
    return records


def thesis_rows(plan: Plan, results: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Every row of the plan: the thesis' values and ours (as written, ★), one record per (row, kind, column)."""
    records = []
    for order, row in enumerate(plan.rows):
        if row.claim:
            columns, thesis = [""], [(None, None)]
        else:
            columns, thesis = thesis_row(row.thesis, row.columns)
        base = {"topic": plan.topic, "order": order, "table": row.table, "name": row.name, "why": row.why,
                "headline": row.headline, "higher": row.higher}
        for column, (mean, std) in zip(columns, thesis, strict=True):
            records.append({**base, "kind": "thesis", "label": "", "column": column, "mean": mean, "std": std,
                            "n": 0, "text": row.claim, "met": None, "study": ""})
        for kind, pick in (("as written", row.as_written), ("★", row.star)):
            records += [{**base, **record} for record in _ours(row, pick, kind, results, columns, thesis)]
    return pd.DataFrame(records)


def _cell(record: pd.Series, digits: int = 2) -> str:
    if isinstance(record["text"], str) and record["text"]:
        return record["text"]
    mean = None if pd.isna(record["mean"]) else float(record["mean"])
    std = None if pd.isna(record["std"]) else float(record["std"])
    if record["kind"] != "thesis" and int(record["n"] or 0) <= 1:
        std = None
    return thesis_fmt(mean, std, digits)


def _met(records: pd.DataFrame) -> bool | None:
    """Whether every column of one (row, kind) is within the thesis' spread; None when not compared."""
    flags = [flag for flag in records["met"] if flag is not None and flag == flag]
    if not flags or len(flags) < len(records):
        return None
    return all(bool(flag) for flag in flags)


def _kind_label(records: pd.DataFrame) -> str:
    first = records.iloc[0]
    label = f"{first['kind']}{', ' + first['label'] if first['label'] and first['kind'] != '★' else ''}"
    label = f"★ {first['label']}" if first["kind"] == "★" and first["label"] else label
    seeds = sorted({int(n) for n in records["n"] if n == n and n})
    if first["kind"] != "thesis" and seeds and seeds != [3]:
        label += f" ({'/'.join(map(str, seeds))} seed{'s' if seeds != [1] else ''})"
    met = _met(records)
    return label + (" ✓" if met else "") if first["kind"] != "thesis" else label


ANCHOR_LINK = re.compile(r"\[([^\]]+)\]\(#[^)]*\)")  # a why's link to an ablation: "[text](#study_key)"
TABLES_FILE = "thesis_tables.md"  # <reports>/<topic>/thesis_tables.md: the opening tables, for the docs to include


def opening_tables(plan: Plan, rows: pd.DataFrame, links: bool = True) -> list[str]:
    """Markdown: one table per thesis table or figure of the plan, in the thesis' layout (its rows, its columns),
    each row as the thesis, the thesis' method as hrc_lab runs it, and hrc_lab's ★ method. ``links``: each of ours
    links the section (anchor) it comes from, and a row's why the ablations it names (in the report; a docs page
    that includes the tables has no such anchors: there they are plain text)."""
    if rows.empty:
        return []
    lines = ["hrc_lab: mean ± std over 3 seeds unless the row says; ✓ within the thesis' spread (or our mean's "
             "standard error) or above (`hrc_lab/report/headline.py`); ★ hrc_lab's method.", ""]
    for table, part in rows.groupby("table", sort=False):
        columns = list(dict.fromkeys(part["column"]))
        header = ["row", "", *[column or "value" for column in columns], "why ours differs"]
        lines += [f"**{table}**", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for _, one in part.groupby("order", sort=True):
            first = True
            for kind in ("thesis", "as written", "★"):
                records = one[one["kind"] == kind]
                if records.empty:
                    continue
                cells = []
                for column in columns:
                    hit = records[records["column"] == column]
                    cells.append(_cell(hit.iloc[0]) if len(hit) else "")
                label, study = _kind_label(records), records.iloc[0]["study"]
                label = f"[{label}](#{study})" if study and links else label
                why = one.iloc[0]["why"] if kind == "as written" else ""
                why = why if links else ANCHOR_LINK.sub(r"\1", why)  # the ablation's anchor is the report's
                lines.append("| " + " | ".join([one.iloc[0]["name"] if first else "", label, *cells, why]) + " |")
                first = False
        lines.append("")
    return lines


def scoreboard_rows(reports: Path) -> pd.DataFrame:
    frames = [pd.read_csv(path) for path in sorted(reports.glob(f"*/{ROWS_FILE}")) if path.stat().st_size > 1]
    frames = [frame for frame in frames if not frame.empty]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


CHAPTER_ORDER = ("ch3", "ch4", "ch5", "ch6", "data")


def _means(one: pd.DataFrame, kind: str, columns: list[str]) -> str:
    """One (row, kind)'s values without their spread, " / "-joined over ``columns`` ("" when there is no such kind)."""
    part = one[one["kind"] == kind]
    if part.empty:
        return ""
    cells = []
    for column in columns:
        hit = part[part["column"].fillna("").astype(str) == column]
        if not len(hit):
            cells.append("–")
            continue
        record = hit.iloc[0].copy()
        record["std"] = math.nan  # the report has the spread
        cells.append(_cell(record))
    return " / ".join(cells)


def write_scoreboard(reports: Path) -> Path:
    """``<reports>/README.md``: one row per headline thesis result of every report built there."""
    rows = scoreboard_rows(reports)
    path = reports / "README.md"
    lines = ["# Scoreboard: the thesis' headline results and ours", "",
             "Generated with the reports (`hrc-lab-report <topic>` rewrites it from every report's "
             f"`<topic>/{ROWS_FILE}`). Values: means over seeds; the report's opening table has the spreads. "
             "Within: every column within the thesis' spread (or our mean's standard error) or above, as written, or "
             "only with ★ hrc_lab's method.", ""]
    if rows.empty:
        path.write_text("\n".join(lines + ["No report built yet."]) + "\n")
        return path
    rows["met"] = rows["met"].map(lambda v: None if pd.isna(v) else str(v).lower() == "true")
    rows = rows[rows["headline"].astype(str).str.lower() == "true"]
    rows["chapter"] = rows["topic"].str.split("_").str[0]
    rows = rows.sort_values(["chapter", "topic", "order"], key=lambda s: s.map(
        lambda v: CHAPTER_ORDER.index(v) if v in CHAPTER_ORDER else v) if s.name == "chapter" else s, kind="stable")
    counts = {"yes": 0, "★ only": 0, "no": 0, "–": 0}
    table = ["| result | thesis | as written | ★ hrc_lab | within | report |", "|---|---|---|---|---|---|"]
    for (topic, _order), one in rows.groupby(["topic", "order"], sort=False):
        first = one.iloc[0]
        columns = [c for c in dict.fromkeys(one["column"].fillna("").astype(str))]
        shown = f" ({' / '.join(columns)})" if len(columns) > 1 else (f" ({columns[0]})" if columns[0] else "")

        as_written = _met(one[one["kind"] == "as written"]) if (one["kind"] == "as written").any() else None
        star = _met(one[one["kind"] == "★"]) if (one["kind"] == "★").any() else None
        verdict = "yes" if as_written else "★ only" if star else "–" if as_written is None and star is None else "no"
        counts[verdict] += 1
        cells = [_means(one, kind, columns) for kind in ("thesis", "as written", "★")]
        table.append(f"| {first['table']}, {first['name']}{shown} | {' | '.join(cells)} | {verdict} | "
                     f"[{topic}]({topic}.md) |")
    total = sum(counts.values())
    lines += [f"{total} rows: within as written {counts['yes']}, only with ★ {counts['★ only']}, not within "
              f"{counts['no']}, not compared {counts['–']}.", "", *table]
    path.write_text("\n".join(lines) + "\n")
    return path
