"""A quiet console: the console scripts filter third-party deprecation warnings (hrc_lab's own still show) and
MLflow's store messages, and a job's log line names its few headline metrics."""

from __future__ import annotations

import os
import subprocess
import warnings

from hrc_lab.console import MAX_SHOWN, headline, quiet_third_party


def test_third_party_deprecations_are_filtered_and_hrc_lab_s_own_are_not():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        quiet_third_party()
        for module in ("torch.jit._script", "lightning.pytorch.utilities._pytree", "hrc_lab.rl.agent"):
            warnings.warn_explicit("old API", FutureWarning, "file.py", 1, module=module)
        warnings.warn_explicit("old API", DeprecationWarning, "file.py", 1, module="gymnasium.envs")
        warnings.warn_explicit("a real problem", RuntimeWarning, "file.py", 1, module="numpy")
    assert [(str(w.message), w.category) for w in caught] == [("old API", FutureWarning),
                                                              ("a real problem", RuntimeWarning)]


def test_a_job_s_log_line_names_its_headline_metrics_and_counts_the_rest():
    metrics = {"sr": 0.98, "sr_case1": 1.0, "fail_pick": 0.02, "n_trials": 100, "planning_ms": 4.1}
    assert headline(metrics) == "sr=0.980, sr_case1=1.000 (+3 more)"
    many = {f"oa_{i}": 0.5 for i in range(10)}
    assert headline(many).count("=") == MAX_SHOWN and headline(many).endswith(f"(+{10 - MAX_SHOWN} more)")
    assert headline({"final_distance": 0.4, "n_env_steps": 16}) == "final_distance=0.400 (+1 more)"


def test_a_sweep_through_joblib_prints_no_third_party_warning(tmp_path, console_script):
    """README command 1's shape (a joblib sweep with its summary), tiny: nothing from the libraries' warnings."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONWARNINGS"}
    env["HRC_LAB_RUNS"] = str(tmp_path / "runs")
    result = subprocess.run(
        [console_script("hrc-lab"), "experiment=ch4/table_4_1", "hydra/launcher=joblib", "env=package_to_order_2of3",
         "reasoning=ours", "seed=0", "trainer.max_epochs=1", "reasoning.steps=5", "protocol.min_demos=10"],
        capture_output=True, text=True, env=env, timeout=240)
    assert result.returncode == 0, result.stderr[-3000:]
    printed = result.stdout + result.stderr
    assert "Warning" not in printed and "deprecated" not in printed and "INFO mlflow" not in printed, printed[-3000:]
    (line,) = [line for line in printed.splitlines() if "[hrc_lab][INFO]" in line]
    assert "sr=" in line and "more)" in line and "pick_span_x_m" not in line
