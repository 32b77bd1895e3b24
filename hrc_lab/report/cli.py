"""``hrc-lab-report <topic>``: write ``reports/<topic>.md``, its tables and plots from the runs of its plan
(:mod:`hrc_lab.report.plans`) in one MLflow store, and the scoreboard ``reports/README.md``.

The report opens with the thesis' tables beside ours, then one section per study of the plan, each built from the
finished runs of that study's variant only; a study without runs says so and names its command. Nothing is kept
from an earlier report."""

from __future__ import annotations

import argparse
from pathlib import Path

from hrc_lab.config import default_tracking_uri
from hrc_lab.console import quiet_third_party


def main(argv: list[str] | None = None) -> None:
    quiet_third_party()
    from hrc_lab.report.build import build_topic
    from hrc_lab.report.plans import PLANS

    parser = argparse.ArgumentParser(prog="hrc-lab-report", description=__doc__)
    parser.add_argument("topic", choices=sorted(PLANS), help="which report to build")
    parser.add_argument("--tracking-uri", default=default_tracking_uri(),
                        help="MLflow tracking URI (default: the store under $HRC_LAB_RUNS, else runs/)")
    parser.add_argument("--out", type=Path, default=Path("reports"), help="folder for the markdown and PNGs")
    args = parser.parse_args(argv)
    path = build_topic(args.topic, args.tracking_uri, args.out)
    print(path.read_text())
    print(f"\nwrote {path} and {args.out / 'README.md'}")


if __name__ == "__main__":
    main()
