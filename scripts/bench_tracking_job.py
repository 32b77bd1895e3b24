"""One job of scripts/bench_tracking.py: a Hydra app run as a joblib sweep (``-m job=range(N)``). Each job makes one
MLflow run and logs ``metrics`` values every step for ``steps`` steps with ``log_batch``, as hrc_lab's RunTracker and
Lightning's MLFlowLogger do, then appends what happened (errors included) to ``<results>/<job>.json``."""

import json
import time
from pathlib import Path

import hydra
from hydra.core.config_store import ConfigStore

ConfigStore.instance().store(name="bench", node={"job": 0, "steps": 200, "metrics": 3, "uri": "???", "bench": "???",
                                                 "results": "???"})


@hydra.main(version_base="1.3", config_path=None, config_name="bench")
def main(cfg) -> None:
    from mlflow.entities import Metric
    from mlflow.tracking import MlflowClient

    out = {"job": cfg.job, "errors": [], "logged": 0}
    begin = time.monotonic()
    client = MlflowClient(cfg.uri)
    try:
        experiment = client.get_experiment_by_name("bench").experiment_id
        run = client.create_run(experiment, run_name=f"bench-{cfg.job}", tags={"bench": cfg.bench})
        for step in range(cfg.steps):
            now = int(time.time() * 1000)
            batch = [Metric(f"m{k}", float(step * k), now, step) for k in range(cfg.metrics)]
            try:
                client.log_batch(run.info.run_id, metrics=batch)
                out["logged"] += 1
            except Exception as error:  # keep going: count every failed write
                out["errors"].append(f"{type(error).__name__}: {error}"[:300])
        client.set_terminated(run.info.run_id, "FINISHED")
    except Exception as error:
        out["errors"].append(f"{type(error).__name__}: {error}"[:300])
    out["seconds"] = time.monotonic() - begin
    Path(cfg.results, f"{cfg.job}.json").write_text(json.dumps(out))


if __name__ == "__main__":
    main()
