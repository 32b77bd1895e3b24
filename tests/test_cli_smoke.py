"""End to end through the CLI's run function, in-process: a tiny Table 4.1 job into a temporary MLflow store, and
a config error raised before anything runs. (A real sweep through the console script: test_sweeps.py.)"""

import pytest

from hrc_lab.registry import ConfigError

TINY = ["trainer.max_epochs=1", "reasoning.steps=5", "protocol.min_demos=10"]


def test_single_run_lands_as_a_named_tagged_run(run_job, base_run_name):
    job = run_job("experiment=ch4/table_4_1", "hydra.mode=RUN", "env=package_to_order_2of3", "seed=3", *TINY)
    run, client = job.run, job.client
    assert base_run_name(run) == "ch4/table_4_1-ours-2of3-seed3" and run.info.status == "FINISHED"
    tags = run.data.tags
    assert {"chapter", "table", "method", "seed", "sweep"} <= set(tags)
    assert tags["chapter"] == "ch4" and tags["table"] == "table_4_1" and tags["seed"] == "3"
    assert tags["sweep"] == "none"  # a single run (hydra.mode=RUN) belongs to no sweep
    assert 0.0 <= run.data.metrics["sr"] <= 1.0 and run.data.metrics["sr"] == job.metrics["sr"]
    assert run.data.metrics["latency_ms_batch1"] > 0
    assert run.data.params["reasoning.name"] == tags["method"] == "ours"
    assert len(client.get_metric_history(run.info.run_id, "train_loss")) == 1  # one value per epoch
    artifacts = {a.path for a in client.list_artifacts(run.info.run_id, "tables")}
    assert {"tables/table_4_1.csv", "tables/table_4_1.md"} <= artifacts
    assert client.list_artifacts(run.info.run_id, "config")
    hydra_files = {a.path for a in client.list_artifacts(run.info.run_id, "hydra")}
    assert {"hydra/config.yaml", "hydra/overrides.yaml"} <= hydra_files
    assert "ch4/table_4_1-ours-2of3-seed3" in job.log and "sr=" in job.log


def test_a_bad_value_raises_config_error_before_any_run(run_job, tmp_path):
    with pytest.raises(ConfigError, match=r"env\.n_selected"):
        run_job("experiment=ch4/table_4_1", "hydra.mode=RUN", "env.n_selected=9")
    with pytest.raises(ConfigError, match="experiment="):
        run_job("hydra.mode=RUN")
    assert not (tmp_path / "runs" / "mlflow.db").exists()  # no MLflow store, let alone a run
