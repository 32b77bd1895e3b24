import subprocess
import sys
import time
from pathlib import Path

import pytest

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
        ("env=error_correction env.task=juggle", "env.task"),
        ("env=error_correction_place env.sim.case=2", "env.sim.case"),
    ],
)
def test_bad_values_fail_naming_the_key(compose_config, override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate_config(compose_config("experiment=ch4/table_4_1", *override.split()))


def test_missing_experiment_is_explained(compose_config):
    with pytest.raises(ConfigError, match="experiment="):
        validate_config(compose_config())


def test_cli_rejects_a_bad_value_within_two_seconds(cli_env):
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "hrc_lab.cli", "experiment=ch4/table_4_1", "env.n_selected=9", "hydra.mode=RUN"],
        capture_output=True,
        text=True,
        env=cli_env,
        timeout=60,
    )
    elapsed = time.perf_counter() - start
    assert result.returncode != 0
    assert "env.n_selected" in result.stderr
    assert elapsed < 2.0, f"validation took {elapsed:.2f} s"


def test_ch5_configs_reject_a_wrong_goal_count(compose_config):
    with pytest.raises(ConfigError, match="env.n_goals"):
        validate_config(compose_config("experiment=ch5/fig_5_7", "env.n_goals=5"))


TOOLS = {"data/collect", "data/render_demo", "ch5/annotate"}  # single jobs (tools), no report section


@pytest.mark.parametrize("experiment", [e for e in EXPERIMENTS if not e.endswith("_quick") and e not in TOOLS])
def test_every_experiment_has_a_report_section_and_topic(compose_config, experiment):
    from hrc_lab.report.build import COMMANDS
    from hrc_lab.report.sections import SECTIONS, TOPICS, load_sections

    cfg = compose_config(f"experiment={experiment}")
    load_sections()
    assert cfg.table in SECTIONS and cfg.table in COMMANDS
    assert (cfg.name, cfg.table) in {part for *_, parts in TOPICS.values() for part in parts}


def test_table_3_1_rejects_an_unknown_stage_start_or_a_negative_placement_noise(compose_config):
    with pytest.raises(ConfigError, match=r"protocol\.stage_starts"):
        validate_config(compose_config("experiment=ch3/table_3_1", "protocol.stage_starts=[planned]"))
    with pytest.raises(ConfigError, match=r"protocol\.placement_noise"):
        validate_config(compose_config("experiment=ch3/table_3_1", "protocol.placement_noise=-0.01"))
