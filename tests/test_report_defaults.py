"""Runs made under an older default read as their own section (hrc_lab.report.defaults)."""

import pandas as pd
import pytest
from omegaconf import OmegaConf

from hrc_lab.config import ConfigError
from hrc_lab.report.defaults import PARAM_PREFIX, pin_changed_defaults, pinned_settings
from hrc_lab.run_naming import variant_of
from hrc_lab.tracking import MAX_PARAM, changed_settings, compose_today, composed_today, schema_defaults

JOB = "experiment=ch3/table_3_1 motion=tc_vi env=error_correction_one_object_case1 seed=1"


def logged_run(overrides: str = JOB, variant: str = "default", variant_overrides: str = "", **changed) -> dict:
    """A run as fetch_runs gives it: today's config as its params, with ``changed`` (dotted keys) logged instead."""
    params = dict(composed_today(tuple(overrides.split())))
    params.update(changed)
    return {"overrides": overrides, "variant": variant, "variant_overrides": variant_overrides,
            "param.logger.tracking_uri": "sqlite:////elsewhere/mlflow.db",  # neutral: never pinned
            **{f"{PARAM_PREFIX}{key}": value for key, value in params.items()}}


def test_a_run_that_today_s_command_repeats_pins_nothing():
    today = composed_today(tuple(JOB.split()))
    assert today["motion.steps"] == "6000" and today["seed"] == "1" and "logger.tracking_uri" not in today
    assert pinned_settings(pd.Series(logged_run())) == []


def test_today_s_config_is_what_hydra_composes_and_names_why_not(compose_config):
    overrides = [*JOB.split(), "motion.steps=2000", "+protocol.extra=1"]
    assert OmegaConf.to_container(compose_today(tuple(overrides))) == OmegaConf.to_container(compose_config(*overrides))
    with pytest.raises(ConfigError, match="motion/gone"):
        compose_today((*JOB.split(), "motion=gone"))
    with pytest.raises(ConfigError, match="no_such_key"):
        compose_today(("experiment=ch3/table_3_1", "motion.no_such_key=1"))


def test_changed_defaults_are_pinned_as_overrides():
    assert pinned_settings(pd.Series(logged_run(**{"motion.steps": "2000"}))) == ["motion.steps=2000"]
    run = logged_run(**{"motion.ndp.path_steps.0": "9", "protocol.placement_noise": "None"})
    today = composed_today(tuple(JOB.split()))
    steps = ",".join(["9", today["motion.ndp.path_steps.1"], today["motion.ndp.path_steps.2"]])
    assert pinned_settings(pd.Series(run)) == [f"motion.ndp.path_steps=[{steps}]", "protocol.placement_noise=null"]


def test_runs_whose_overrides_no_longer_compose_or_were_not_logged_keep_their_variant():
    gone = logged_run(**{"motion.steps": "2000"}) | {"overrides": JOB + " motion=gone"}
    assert pinned_settings(pd.Series(gone)) == []
    assert pinned_settings(pd.Series({"variant": "default", "param.motion.steps": "2000"})) == []
    assert composed_today(("experiment=ch3/table_3_1", "motion.no_such_key=1")) is None


def test_pinned_runs_move_to_the_variant_their_settings_name():
    ablation, _ = variant_of(["protocol.dagger_rounds=2"], [])
    frame = pd.DataFrame([
        logged_run(),
        logged_run(**{"motion.steps": "2000"}),
        logged_run(JOB + " protocol.dagger_rounds=2", ablation, "protocol.dagger_rounds=2", **{"motion.steps": "2000"}),
    ])
    frame.loc[2, "param.protocol.dagger_rounds"] = "2"
    pinned = pin_changed_defaults(frame)
    assert list(pinned["pinned"]) == ["", "motion.steps=2000", "motion.steps=2000"]
    assert pinned.loc[0, "variant"] == "default"
    # the same variant as a job given the override on the command line
    assert pinned.loc[1, "variant"] == variant_of(["motion.steps=2000"], [])[0]
    assert pinned.loc[1, "variant_overrides"] == "motion.steps=2000"
    assert pinned.loc[2, "variant_overrides"] == "motion.steps=2000 protocol.dagger_rounds=2"
    assert list(pinned["logged_variant_overrides"]) == ["", "", "protocol.dagger_rounds=2"]


def test_a_protocol_key_read_only_by_other_methods_is_not_pinned():
    """Table 4.3's motion_demos changes ours' runs, not DRL's (the schema field's ``read_by``)."""
    job = "experiment=ch4/table_4_3 env=package_to_order_3of5 seed=0"
    for method, pinned in (("drl", []), ("ours", ["protocol.motion_demos=fixed"])):
        run = logged_run(f"{job} tamp={method}", **{"protocol.motion_demos": "fixed"}) | {"method": method}
        assert pinned_settings(pd.Series(run)) == pinned


def test_an_override_that_today_s_defaults_give_leaves_the_variant():
    """Runs given motion.steps=6000 before 6000 became the default are default runs today."""
    redundant, _ = variant_of(["motion.steps=6000"], [])
    frame = pd.DataFrame([logged_run(JOB + " motion.steps=6000", redundant, "motion.steps=6000"),
                          logged_run(JOB + " motion.steps=6000 protocol.dagger_rounds=2", "v1",
                                     "motion.steps=6000 protocol.dagger_rounds=2")])
    frame.loc[1, "param.protocol.dagger_rounds"] = "2"
    moved = pin_changed_defaults(frame)
    assert list(moved["variant"]) == ["default", variant_of(["protocol.dagger_rounds=2"], [])[0]]
    assert list(moved["variant_overrides"]) == ["", "protocol.dagger_rounds=2"]


def test_a_changed_nested_list_is_pinned_whole():
    from hrc_lab.report.defaults import _list_override

    logged = {"grasp.anchors.0.0": "24", "grasp.anchors.0.1": "40", "grasp.anchors.1.0": "56",
              "grasp.anchors.1.1": "80", "grasp.steps": "3000"}
    assert _list_override(logged, "grasp.anchors") == "[[24,40],[56,80]]"


def test_one_rule_reads_an_older_run_under_today_s_config():
    """changed_settings: what the run logged is compared, a key added since only as its schema default (and only in a
    node the run logged), a key gone since is a change, and a value is compared as MLflow keeps it (its first
    MAX_PARAM characters)."""
    long = "x" * (MAX_PARAM + 10)
    logged = {"motion.steps": "2000", "seed": "1", "gone": "1", "long": long[:MAX_PARAM]}
    today = {"motion.steps": "6000", "seed": "1", "motion.added_since": "0", "protocol.new": "1", "long": long}
    assert changed_settings(logged, today) == ["gone", "motion.steps"]
    assert changed_settings({}, today) == []
    # a key added since to a node the run logged is compared as its schema default: the run ran with it
    assert changed_settings(logged, today, {"motion.added_since": "0", "protocol.new": "0"}) == ["gone", "motion.steps"]
    added = changed_settings(logged, today, {"motion.added_since": "1"})
    assert added == ["gone", "motion.added_since", "motion.steps"]


def test_a_key_added_since_that_an_experiment_sets_away_from_its_schema_default_is_pinned():
    """Fig. 3.13 sets motion.place_through_grasp (added with the schema default False) to True: a run from before
    the key existed placed without it, so it is pinned to the schema default, not read as today's default run."""
    job = "experiment=ch3/fig_3_13 env=error_correction_one_object_case1 rl.lam=0.7 seed=0"
    defaults = schema_defaults(compose_today(tuple(job.split())))
    assert defaults["motion.place_through_grasp"] == "False" and defaults["rl.steps_per_subtask"] == "40"
    run = logged_run(job)
    assert pinned_settings(pd.Series(run)) == []
    del run[f"{PARAM_PREFIX}motion.place_through_grasp"]
    assert pinned_settings(pd.Series(run)) == ["motion.place_through_grasp=False"]
