import itertools
import math
import subprocess
import sys
from pathlib import Path

import pytest
from hydra.errors import ConfigCompositionException

from hrc_lab.config import validate_config
from hrc_lab.registry import ConfigError

EXPERIMENTS = sorted(
    str(p.relative_to(Path(__file__).resolve().parents[1] / "conf" / "experiment")).removesuffix(".yaml")
    for p in (Path(__file__).resolve().parents[1] / "conf" / "experiment").rglob("*.yaml")
)


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_config_composes_and_validates(compose_config, experiment):
    validated = validate_config(compose_config(f"experiment={experiment}"))
    assert validated.protocol is not None and validated.env.cell


@pytest.mark.parametrize(
    "override, key",
    [
        ("env.n_selected=7", "env.n_selected"),
        ("+reasoning.hiden=3", "reasoning.hiden"),
        ("reasoning.hidden=abc", "reasoning.hidden"),
        ("reasoning.lr=-1", "reasoning.lr"),
        ("+trainer.max_epoch=3", "trainer.max_epoch"),
        ("+env.n_object=3", "env.n_object"),
        ("protocol.n_folds=1", "protocol.n_folds"),
        ("+foo=1", "foo"),
        ("seed=-2", "seed"),
        ("logger.tracking_uri=runs/mlflow.db", "logger.tracking_uri"),
        ("reasoning=gnn reasoning.label_scheme=goal", "reasoning.label_scheme"),
        ("env.sim.case=3", "env.sim.case"),
        ("env.sim.success_threshold=-0.1", "env.sim.success_threshold"),
        ("+env.sim.horizn=5", "env.sim.horizn"),
        ("experiment=ch3/table_3_1 env.task=juggle", "env.task"),
        ("experiment=ch3/table_3_1 env=error_correction_place env.sim.case=2", "env.sim.case"),
        ("experiment=ch3/fig_3_13 rl.n_envs=0", "rl.n_envs"),
        ("experiment=ch3/fig_3_13 rl.cycles_per_epoch=0", "rl.cycles_per_epoch"),
        ("experiment=ch3/fig_3_13 protocol.subgoal_path=joints", "protocol.subgoal_path"),
        ("experiment=ch3/table_3_1 protocol.subgoal_path=lip", "protocol.subgoal_path"),
        ("experiment=ch4/table_4_3 rl.episodes_per_cycle=3 rl.n_envs=2", "rl.episodes_per_cycle"),
        ("experiment=rl/fetch protocol.env_id=FetchJuggle-v4", "protocol.env_id"),
    ],
)
def test_bad_values_fail_naming_the_key(compose_config, override, key):
    """A wrong type fails when Hydra composes (every group's schema is in its ConfigStore), an unknown key or an
    impossible value in validate_config; both name the key."""
    with pytest.raises((ConfigError, ConfigCompositionException), match=key.replace(".", r"\.")):
        experiment = [] if override.startswith("experiment=") else ["experiment=ch4/table_4_1"]
        validate_config(compose_config(*experiment, *override.split()))


def test_missing_experiment_is_explained(compose_config):
    with pytest.raises(ConfigError, match="experiment="):
        validate_config(compose_config())


def test_cli_exits_2_naming_the_bad_key(cli_env, console_script):
    result = subprocess.run(
        [console_script("hrc-lab"), "experiment=ch4/table_4_1", "env.n_selected=9", "hydra.mode=RUN"],
        capture_output=True,
        text=True,
        env=cli_env,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr[-3000:]
    assert "config error" in result.stderr and "env.n_selected" in result.stderr


@pytest.mark.parametrize("override, expected", [("reasoning=nope", "Available options in 'reasoning'"),
                                                ("reasoning.hidden=abc", "reasoning.hidden")])
def test_cli_exits_2_when_hydra_cannot_compose(cli_env, console_script, override, expected):
    """An unknown group option or a value of the wrong type is a config error too (issue 49: Hydra exited 1)."""
    result = subprocess.run(
        [console_script("hrc-lab"), "experiment=ch4/table_4_1", override, "hydra.mode=RUN"],
        capture_output=True,
        text=True,
        env=cli_env,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr[-3000:]
    assert "config error" in result.stderr and expected in result.stderr


HEAVY = ("torch", "lightning", "mlflow", "robosuite", "mujoco", "sklearn", "torch_geometric", "mediapipe")

VALIDATE_IN_A_FRESH_INTERPRETER = f"""
import sys
from hydra import compose, initialize_config_dir
from hrc_lab.cli import run
from hrc_lab.run_naming import CONF_DIR
from hrc_lab.config import validate_config
from hrc_lab.registry import ConfigError

with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
    for experiment in {EXPERIMENTS!r}:
        validate_config(compose("config", overrides=["experiment=" + experiment]))
    try:
        run(compose("config", overrides=["experiment=ch4/table_4_1", "env.n_selected=9"]))
    except ConfigError:
        pass
    else:
        sys.exit("run() accepted env.n_selected=9")
print(" ".join(sorted(name for name in {HEAVY!r} if name in sys.modules)) or "none")
"""


def test_validation_imports_nothing_heavy(cli_env):
    """A bad key fails fast because validating (every experiment, and run() up to its ConfigError) imports none of
    torch, lightning, MLflow, the simulators: checked in a fresh interpreter, not with a clock."""
    script = [sys.executable, "-c", VALIDATE_IN_A_FRESH_INTERPRETER]
    result = subprocess.run(script, capture_output=True, text=True, env=cli_env, timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.split() == ["none"], f"validation imported {result.stdout.strip()}"


def test_ch5_configs_reject_a_wrong_goal_count(compose_config):
    with pytest.raises(ConfigError, match="env.n_goals"):
        validate_config(compose_config("experiment=ch5/fig_5_7", "env.n_goals=5"))


# single jobs (tools), no report section
TOOLS = {"data/collect", "data/render_demo", "ch5/annotate"}


@pytest.mark.parametrize("experiment", [e for e in EXPERIMENTS if not e.endswith("_quick") and e not in TOOLS])
def test_every_experiment_has_a_report_section_and_a_study(compose_config, experiment):
    from hrc_lab.report.plans import PLANS
    from hrc_lab.report.sections import SECTIONS, load_sections

    cfg = compose_config(f"experiment={experiment}")
    load_sections()
    assert cfg.table in SECTIONS
    studies = [study for plan in PLANS.values() for study in plan.studies
               if experiment == study.experiment or experiment in study.also]
    assert studies and all(study.table == cfg.table and study.mlflow_experiment == cfg.name for study in studies)


@pytest.mark.parametrize("override,key", [
    ("protocol.stage_starts=[planned]", r"protocol\.stage_starts"),
    ("protocol.placement_noise=-0.01", r"protocol\.placement_noise"),
    ("protocol.action_noise=-0.01", r"protocol\.action_noise must be >= 0 rad"),
    ("protocol.stage_labels=oracle",
     r"protocol\.stage_labels must be one of \['classifier', 'picking_classifier', 'ground_truth'\]"),
    ("motion.planner_input=relative", r"motion\.planner_input must be one of \['full', 'selected'\]"),
])
def test_table_3_1_protocol_errors_name_the_key(compose_config, override, key):
    with pytest.raises(ConfigError, match=key):
        validate_config(compose_config("experiment=ch3/table_3_1", override))


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_module_an_experiment_sweeps_over_is_accepted_by_its_protocol(experiment):
    """A sweep list names only modules its protocol runs with (``ACCEPTS``), so no sweep stops at its first job of a
    module added to the list but not to the protocol (static: the yaml files, no composition)."""
    from omegaconf import OmegaConf

    from hrc_lab.experiments.schemas import ACCEPTS

    conf = Path(__file__).resolve().parents[1] / "conf"
    raw = OmegaConf.load(conf / "experiment" / f"{experiment}.yaml")
    protocol = OmegaConf.select(raw, "protocol.name")
    params = OmegaConf.select(raw, "hydra.sweeper.params") or {}
    for group, values in params.items():
        if group in ("env", "seed") or protocol not in ACCEPTS or "." in group:
            continue
        for value in str(values).split(","):
            option = OmegaConf.load(conf / group / f"{value.strip()}.yaml")
            name = option.get("name") or OmegaConf.select(option, f"{group}.name")  # a global-package option
            assert name in ACCEPTS[protocol].get(group, ("none",)), f"{experiment}: {group}={value} ({name})"


def test_the_quick_table_runs_jobs_of_the_full_table(compose_config):
    """README command 1 must not misrepresent a method (issue 24): each of its jobs is one of ch4/table_4_1's, same
    config but the experiment name, so every number it prints is one the full table also reports."""
    from omegaconf import OmegaConf

    def sweep(experiment):
        params = compose_config(f"experiment={experiment}", return_hydra_config=True).hydra.sweeper.params
        return {key: _values(spec) for key, spec in params.items()}

    def job(experiment, overrides):
        cfg = OmegaConf.to_container(compose_config(f"experiment={experiment}", *overrides), resolve=True)
        return {key: value for key, value in cfg.items() if key != "name"}

    quick, full = sweep("ch4/table_4_1_quick"), sweep("ch4/table_4_1")
    assert quick.keys() == full.keys() and all(set(quick[k]) <= set(full[k]) for k in quick)
    jobs = [[f"{k}={v}" for k, v in zip(quick, values)] for values in itertools.product(*quick.values())]
    assert 0 < len(jobs) < math.prod(len(v) for v in full.values())
    for overrides in jobs:
        assert job("ch4/table_4_1_quick", overrides) == job("ch4/table_4_1", overrides), overrides


def _values(spec) -> list[str]:
    """The values of a basic sweeper's parameter: a comma list or range(...)."""
    spec = str(spec)
    if spec.startswith("range("):
        return [str(i) for i in range(*map(int, spec[6:-1].split(",")))]
    return [v.strip() for v in spec.split(",")]
