"""Sweeps through Hydra launchers (slow: several processes, each importing torch)."""

import subprocess

import pytest
from mlflow.tracking import MlflowClient

TINY = ["trainer.max_epochs=1", "reasoning.steps_per_epoch=5", "protocol.min_demos=10"]


@pytest.mark.slow
def test_joblib_launcher_runs_jobs_in_parallel_into_one_experiment(tmp_path, cli_env, console_script):
    command = [
        console_script("hrc-lab"),
        "-m",
        "experiment=ch4/table_4_1",
        "hydra/launcher=joblib",
        "hydra.launcher.n_jobs=2",
        "env=package_to_order_2of3,package_to_order_3of3",
        "reasoning=ours,mlp",
        "seed=0",
        *TINY,
    ]
    result = subprocess.run(command, capture_output=True, text=True, env=cli_env, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    client = MlflowClient(f"sqlite:///{tmp_path / 'runs' / 'mlflow.db'}")
    experiment = client.get_experiment_by_name("ch4/table_4_1")
    runs = [r for r in client.search_runs([experiment.experiment_id]) if r.data.tags.get("kind") != "summary"]
    assert len(runs) == 4 and all(r.info.status == "FINISHED" for r in runs)
    assert len({r.data.tags["sweep"] for r in runs}) == 1


@pytest.mark.slow
def test_single_run_mode(tmp_path, cli_env, console_script):
    command = [
        console_script("hrc-lab"),
        "experiment=ch4/table_4_1",
        "hydra.mode=RUN",
        "env=package_to_order_2of3",
        "seed=3",
        *TINY,
    ]
    result = subprocess.run(command, capture_output=True, text=True, env=cli_env, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    client = MlflowClient(f"sqlite:///{tmp_path / 'runs' / 'mlflow.db'}")
    (run,) = client.search_runs([client.get_experiment_by_name("ch4/table_4_1").experiment_id])
    assert run.info.run_name == "ch4/table_4_1-ours-2of3-seed3" and run.data.tags["sweep"] == "none"
