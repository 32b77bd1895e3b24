"""Hyper-parameter search (hydra/sweeper=optuna, conf/search, docs/search.md): a bad search space fails before the
first trial naming its key (exit 2); a tiny study logs one MLflow run per trial under one study tag and prints its
best trial."""

import subprocess

import pytest
from mlflow.tracking import MlflowClient
from omegaconf import open_dict, read_write

from hrc_lab.config import validate_config
from hrc_lab.registry import ConfigError
from hrc_lab.run_naming import variant_of
from hrc_lab.search import check_search_space, objective_of

TINY = ["protocol.epochs=1", "rl.cycles_per_epoch=1", "rl.gradient_steps=5", "protocol.eval_episodes=2"]


@pytest.mark.parametrize("search, experiment", [("rl_fetch", "rl/fetch"), ("ch6_solver", "ch6/table_6_1")])
def test_the_shipped_search_spaces_compose_validate_and_pass_their_checks(compose_config, search, experiment):
    cfg = compose_config(f"experiment={experiment}", f"search={search}", return_hydra_config=True)
    assert cfg.hydra.runtime.choices["hydra/sweeper"] == "optuna" and cfg.search.objective
    check_search_space(cfg)
    validate_config(cfg)


@pytest.mark.parametrize("override, named", [
    ("rl.learnin_rate=interval(0.001,0.01)", "rl.learnin_rate"),  # unknown key
    ("rl.tau=interval(0.1,0.01)", "rl.tau"),  # low >= high
    ("rl.learning_rate=tag(log,interval(0,0.01))", "rl.learning_rate"),  # log range from 0
    ("rl.batch_size=range(256,64)", "rl.batch_size"),  # empty range
])
def test_a_bad_search_space_fails_before_the_first_trial_naming_the_key(compose_config, override, named):
    cfg = compose_config("experiment=rl/fetch", "search=rl_fetch", return_hydra_config=True)
    with read_write(cfg.hydra):
        cfg.hydra.overrides.task.append(override)  # as `hrc-lab -m ... <override>` puts it there
    with pytest.raises(ConfigError, match=named.replace(".", r"\.")):
        check_search_space(cfg)


def test_an_unknown_key_of_a_search_file_is_named(compose_config, tmp_path):
    cfg = compose_config("experiment=rl/fetch", "search=rl_fetch", return_hydra_config=True)
    with read_write(cfg.hydra), open_dict(cfg.hydra):
        cfg.hydra.sweeper.params["rl.hiden"] = "choice(64,128)"
    with pytest.raises(ConfigError, match=r"hydra\.sweeper\.params\.rl\.hiden"):
        check_search_space(cfg)
    cfg = compose_config("experiment=ch4/table_4_1", "hydra/sweeper=optuna", return_hydra_config=True)
    check_search_space(cfg)  # no search file: the experiment's grid is the space, its "sr" the objective
    assert objective_of(cfg) == "sr"


def test_the_cli_exits_2_naming_the_bad_key_before_any_trial(cli_env, console_script, tmp_path):
    result = subprocess.run([console_script("hrc-lab"), "-m", "experiment=rl/fetch", "search=rl_fetch",
                             "rl.tau=interval(0.1,0.01)"], capture_output=True, text=True, env=cli_env, timeout=60)
    assert result.returncode == 2, result.stderr[-3000:]
    assert "config error" in result.stderr and "rl.tau" in result.stderr
    assert "Launching" not in result.stdout + result.stderr
    assert not (tmp_path / "runs" / "mlflow.db").exists()


def test_a_study_of_the_default_objective_maximises_it(compose_config):
    """Without a search file a trial reports its success rate (``sr``): the study maximises it unless the command
    line gives a direction (Optuna's default, minimize, looked for the worst settings)."""
    from hrc_lab.search import StudyCallback

    def direction(*overrides):
        config = compose_config("experiment=ch4/table_4_1_quick", "hydra/sweeper=optuna", *overrides,
                                return_hydra_config=True)
        config.hydra.overrides.hydra = [o for o in overrides if o.startswith("hydra.")]
        config.hydra.sweep.dir = "sweep"
        StudyCallback().on_multirun_start(config)
        return str(config.hydra.sweeper.direction)

    assert direction().endswith("maximize")
    assert direction("hydra.sweeper.direction=minimize").endswith("minimize")
    assert direction("search.objective=collision_rate").endswith("minimize")


def test_a_trial_is_a_variant_of_its_own():
    """Under the Optuna sweeper no key is a grid key: a trial's sampled values always make a variant."""
    trial = ["rl.learning_rate=0.001", "seed=0", "experiment=rl/fetch", "search=rl_fetch"]
    assert variant_of(trial, [])[0] != "default"
    assert variant_of(trial, [])[0] != variant_of(["rl.learning_rate=0.002", *trial[1:]], [])[0]


@pytest.mark.slow
def test_a_tiny_study_logs_one_run_per_trial_and_prints_the_best(cli_env, console_script, tmp_path):
    """~35 s on 2 busy cores (2 FetchReach trials of one 1-cycle epoch; most of it imports); the done-when command of
    issue 50 (4 trials) is docs/search.md's."""
    result = subprocess.run([console_script("hrc-lab"), "-m", "experiment=rl/fetch", "search=rl_fetch",
                             "hydra/sweeper=optuna", "hydra.sweeper.n_trials=2", *TINY],
                            capture_output=True, text=True, env=cli_env, timeout=240)
    assert result.returncode == 0, result.stderr[-3000:]
    client = MlflowClient(f"sqlite:///{tmp_path}/runs/mlflow.db")
    runs = client.search_runs([client.get_experiment_by_name("rl/fetch").experiment_id])
    trials = [r for r in runs if r.data.tags.get("kind") != "summary"]
    summaries = [r for r in runs if r.data.tags.get("kind") == "summary"]
    assert len(trials) == 2 and all(r.info.status == "FINISHED" for r in trials)
    studies = {r.data.tags["study"] for r in trials}
    assert len(studies) == 1 and {r.data.tags["study"] for r in summaries} == studies
    assert all(r.data.tags["variant"] != "default" for r in trials)
    assert len({r.data.tags["variant"] for r in trials}) == 2
    assert all("final_success_rate" in r.data.metrics for r in trials)
    best = summaries[0].data.tags["best_run"]
    assert best in {r.info.run_id for r in trials}
    assert f"study {studies.pop()}: best trial" in result.stdout and best in result.stdout
