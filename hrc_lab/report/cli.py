"""``hrc-lab-report <topic>``: write ``reports/<topic>.md`` and its plots from the MLflow runs of its tables.

Each table reads its default runs (no override beyond the experiment's own sweep keys); every ablation variant
present (runs with other overrides, e.g. ``protocol.demos=60``) follows in its own section. ``--update`` keeps the
sections of the existing report whose runs the store does not hold."""

from __future__ import annotations

import argparse
from pathlib import Path

from hrc_lab.config import default_tracking_uri
from hrc_lab.report.build import build_topic
from hrc_lab.report.sections import TOPICS


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="hrc-lab-report", description=__doc__)
    parser.add_argument("topic", choices=sorted(TOPICS), help="which report to build")
    parser.add_argument("--tracking-uri", default=default_tracking_uri(),
                        help="MLflow tracking URI (default: the store under $HRC_LAB_RUNS, else runs/)")
    parser.add_argument("--out", type=Path, default=Path("reports"), help="folder for the markdown and PNGs")
    parser.add_argument(
        "--sweep",
        default=None,
        metavar="ID",
        help="read only the runs of this sweep (its folder name, e.g. 2026-11-23_19-31-20; MLflow tag `sweep`) "
        "in every section; default: the newest finished run of every job across sweeps",
    )
    parser.add_argument(
        "--update",
        action="store_true",
        help="keep each section of the existing <out>/<topic>.md whose runs this store (or sweep) does not hold, "
        "as it is, and rebuild the others (e.g. one figure re-run on a machine whose store lacks the rest)",
    )
    args = parser.parse_args(argv)
    path = build_topic(args.topic, args.tracking_uri, args.out, sweep=args.sweep, update=args.update)
    print(path.read_text())
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
