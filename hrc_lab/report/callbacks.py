"""Hydra callback of the experiment sweeps: validate once and set up the MLflow store before the jobs start,
then print the table of the sweep's runs beside the thesis' values when they are done."""

from __future__ import annotations

import sys
import traceback
from pathlib import Path

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from hrc_lab.config import ConfigError, validate_config


class SweepSummary(Callback):
    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        try:
            validated = validate_config(config)
        except ConfigError as err:
            print(f"hrc-lab: config error: {err}", file=sys.stderr)
            sys.exit(2)
        from mlflow.tracking import MlflowClient

        from hrc_lab.tracking import ensure_experiment, resolve_tracking_uri

        # Create the store and the experiment here, once, so parallel jobs do not race to migrate the database.
        client = MlflowClient(resolve_tracking_uri(validated.logger.tracking_uri))
        ensure_experiment(client, config.name, validated.logger.artifact_root)

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        """Print and log the sweep's summary. If that fails, the sweep exits 1 (Hydra would only warn about an
        exception raised here and exit 0, as if all were well); the jobs' own runs stay as they ended."""
        try:
            self._summarise(config)
        except Exception:
            from hrc_lab.report.plans import PLANS

            traceback.print_exc()
            topic = next((plan.topic for plan in PLANS.values()
                          if any(study.mlflow_experiment == config.name for study in plan.studies)), "<topic>")
            print(f"hrc-lab: the sweep's jobs ended but its summary failed (traceback above); its runs are in MLflow "
                  f"(sweep {Path(config.hydra.sweep.dir).name}); its report: `hrc-lab-report {topic}`",
                  file=sys.stderr)
            sys.exit(1)

    @staticmethod
    def _summarise(config: DictConfig) -> None:
        from hrc_lab.report.build import sections_from, write_section
        from hrc_lab.report.plans import PLANS
        from hrc_lab.report.runs import fetch_runs
        from hrc_lab.tracking import LoggerConfig, RunTracker

        sweep_dir = Path(config.hydra.sweep.dir)
        uri = config.logger.tracking_uri
        # This sweep's runs only, of whatever variant they carry (a sweep with extra overrides is an ablation; one
        # that sweeps an extra key holds several variants, each summarised apart).
        sections = sections_from(fetch_runs(uri, config.name, sweep_dir.name, variant=None), str(config.table))
        if not sections:
            print(f"hrc-lab: no finished runs in sweep {sweep_dir}", file=sys.stderr)
            return
        studies = {(study.mlflow_experiment, study.variant): study for plan in PLANS.values() for study in plan.studies}
        parts = []
        for variant, _, section in sections:
            stem = config.table if variant == "default" else f"{config.table}_{variant}"
            study = studies.get((str(config.name), variant))
            command = study.command if study else " ".join(["hrc-lab", *sys.argv[1:]])
            parts.append(write_section(section, sweep_dir / "summary", uri, stem, command))
        markdown = "\n".join(parts)
        (sweep_dir / "summary.md").write_text(markdown)
        logger = LoggerConfig(tracking_uri=uri, artifact_root=config.logger.artifact_root)
        tags = {"kind": "summary", "table": str(config.table), "sweep": sweep_dir.name, "chapter": str(config.chapter),
                "variant": ",".join(variant for variant, _, _ in sections)}
        with RunTracker(logger, config.name, f"{config.name}-summary-{sweep_dir.name}", tags) as tracker:
            tracker.log_artifact(sweep_dir / "summary", "summary")
            tracker.log_artifact(sweep_dir / "summary.md", "summary")
        print(f"\n{markdown}\nSweep folder: {sweep_dir}  (rebuild the committed report with hrc-lab-report)")
