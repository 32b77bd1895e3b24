"""End to end through the console scripts: a tiny Table 4.1 sweep into a temporary MLflow store, then the report."""

import subprocess

import pytest
from mlflow.tracking import MlflowClient

TINY = ["trainer.max_epochs=1", "reasoning.steps_per_epoch=5", "protocol.min_demos=10"]


@pytest.fixture(scope="module")
def tiny_sweep(tmp_path_factory, console_script):
    runs = tmp_path_factory.mktemp("smoke") / "runs"
    env = {**__import__("os").environ, "HRC_LAB_RUNS": str(runs), "PYTHONWARNINGS": "ignore"}
    command = [
        console_script("hrc-lab"),
        "-m",
        "experiment=ch4/table_4_1",
        "env=package_to_order_2of3",
        "reasoning=ours,mlp",
        "seed=0,1",
        *TINY,
    ]
    result = subprocess.run(command, capture_output=True, text=True, env=env, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    return runs, env, result.stdout


def test_sweep_lands_as_named_tagged_runs(tiny_sweep):
    runs, _, _ = tiny_sweep
    client = MlflowClient(f"sqlite:///{runs / 'mlflow.db'}")
    experiment = client.get_experiment_by_name("ch4/table_4_1")
    found = client.search_runs([experiment.experiment_id])
    jobs = [r for r in found if r.data.tags.get("kind") != "summary"]
    names = sorted(r.info.run_name for r in jobs)
    assert names == [f"ch4/table_4_1-{m}-2of3-seed{s}" for m in ("mlp", "ours") for s in (0, 1)]
    for run in jobs:
        tags = run.data.tags
        assert {"chapter", "table", "method", "seed", "sweep"} <= set(tags)
        assert tags["chapter"] == "ch4" and tags["table"] == "table_4_1" and tags["sweep"] != "none"
        assert 0.0 <= run.data.metrics["sr"] <= 1.0
        assert run.data.metrics["latency_ms_batch1"] > 0
        assert run.data.params["reasoning.name"] == run.data.tags["method"]
        history = client.get_metric_history(run.info.run_id, "train_loss")
        assert len(history) == 1  # one value per epoch (max_epochs=1)
        artifacts = {a.path for a in client.list_artifacts(run.info.run_id, "tables")}
        assert {"tables/table_4_1.csv", "tables/table_4_1.md"} <= artifacts
        assert client.list_artifacts(run.info.run_id, "config")
        assert client.list_artifacts(run.info.run_id, "hydra")


def test_sweep_prints_the_summary_table(tiny_sweep):
    _, _, stdout = tiny_sweep
    assert "Table 4.1" in stdout and "(thesis 1.00 ± 0.00)" in stdout


def test_report_command_writes_markdown_and_plot(tiny_sweep, tmp_path, console_script):
    runs, env, _ = tiny_sweep
    command = [
        console_script("hrc-lab-report"),
        "ch4_reasoning",
        "--tracking-uri",
        f"sqlite:///{runs / 'mlflow.db'}",
        "--out",
        str(tmp_path),
    ]
    result = subprocess.run(command, capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    report = (tmp_path / "ch4_reasoning.md").read_text()
    assert "| Ours" in report and "| MLP" in report
    assert (tmp_path / "ch4_reasoning" / "table_4_1.png").stat().st_size > 1000
    assert "No finished runs yet" in report  # fig 4.7 and the others were not run here
