"""Every default is written once, in its dataclass: no yaml repeats a value of its schema's defaults.

Each group file ``conf/<group>/<file>.yaml`` extends the schema of the name it composes to (``schema/<group>/<name>``
in Hydra's ConfigStore; the trainer's is :class:`hrc_lab.config.TrainerConfig`), and each experiment file's
``protocol`` node is validated against the protocol schema of its ``name`` (:mod:`hrc_lab.experiments.schemas`).
A file is read raw (not composed), so a value it inherits from a parent yaml is counted in the parent only; a value
equal to the default is allowed where it resets a different value inherited from a parent file.

An experiment file can leave a protocol default out only once its ``protocol`` node extends the protocol's schema in
Hydra's ConfigStore (``schema/protocol/<name>``): otherwise ``protocol.<key>=...`` on the command line would need a
``+``. Until :func:`hrc_lab.config.register_schemas` stores them, the protocol check is an expected failure.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from omegaconf import OmegaConf

from hrc_lab.config import TrainerConfig, group_registries
from hrc_lab.experiments import PROTOCOLS
from hrc_lab.motion.configs import SubgoalConfig

CONF = Path(__file__).resolve().parents[1] / "conf"
GROUPS = ("env", "reasoning", "motion", "perception", "grasp", "rl", "tamp")
GLOBAL_PRESETS = ("tamp",)  # groups whose files are presets over other groups (@package _global_, their node below)
SKIPPED_KEYS = {"name", "defaults"}


def flatten(node: dict, prefix: str = "") -> dict[str, Any]:
    """``{"ndp": {"hidden": 128}}`` -> ``{"ndp.hidden": 128}`` (an empty dict stays a value)."""
    flat = {}
    for key, value in node.items():
        if isinstance(value, dict) and value:
            flat.update(flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def schema_defaults(schema: type) -> dict[str, Any]:
    return flatten(OmegaConf.to_container(OmegaConf.structured(schema), resolve=False))


def _raw(path: Path) -> dict:
    return yaml.safe_load(path.read_text()) or {}


def _parents(path: Path, raw: dict) -> list[Path]:
    """The yaml files ``path`` extends through its defaults list (not the ConfigStore schemas, not overrides)."""
    parents = []
    for entry in raw.get("defaults") or []:
        if not isinstance(entry, str) or entry == "_self_" or entry.startswith("/schema/"):
            continue
        parent = CONF / f"{entry[1:]}.yaml" if entry.startswith("/") else path.parent / f"{entry}.yaml"
        if not parent.exists():  # relative to the config group's root, e.g. data/collect in conf/experiment
            parent = CONF / path.relative_to(CONF).parts[0] / f"{entry}.yaml"
        if parent.exists():  # else a ConfigStore node, e.g. the trainer's schema
            parents.append(parent)
    return parents


def _node(raw: dict, node: str | None) -> dict:
    values = (raw.get(node) or {}) if node else raw
    return flatten({k: v for k, v in values.items() if k not in SKIPPED_KEYS})


def inherited(path: Path, node: str | None) -> dict[str, Any]:
    """The values ``path`` inherits from the yaml files it extends (the later parent wins), read raw."""
    values: dict[str, Any] = {}
    for parent in _parents(path, _raw(path)):
        values |= inherited(parent, node) | _node(_raw(parent), node)
    return values


def repeated_defaults(path: Path, schema: type, node: str | None = None) -> list[str]:
    """The values of ``path`` (of its top-level ``node``, e.g. ``protocol``; None: the whole file) that equal the
    default of ``schema`` for their key, unless they reset a different value inherited from a parent yaml."""
    defaults, parents = schema_defaults(schema), inherited(path, node)
    file = path.relative_to(CONF.parent)
    return [
        f"{file}: {key}={value!r} repeats the default of {schema.__name__}"
        for key, value in _node(_raw(path), node).items()
        if not (isinstance(value, str) and "${" in value)
        and key in defaults and value == defaults[key]
        and not (key in parents and parents[key] != defaults[key])
    ]


@pytest.fixture(scope="module")
def uses() -> list[tuple[Path, type, str | None, str]]:
    """(yaml file, schema, node, registry entry) for every yaml that uses a registered schema."""
    registries = group_registries()
    found = [(path, TrainerConfig, None, "trainer") for path in sorted((CONF / "trainer").glob("*.yaml"))]
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
            for group in GROUPS:
                for path in sorted((CONF / group).glob("*.yaml")):
                    preset = group in GLOBAL_PRESETS
                    # the file's own name key (a composition only where it inherits the name from a parent file)
                    name = (_raw(path).get(group) or {}).get("name") if preset else _raw(path).get("name")
                    if name is None:
                        name = (compose("config", overrides=[f"{group}={path.stem}"]) if preset
                                else compose(config_name=f"{group}/{path.stem}"))[group].name
                    if name != "none":
                        found.append((path, registries[group].get(name).schema, group if preset else None,
                                      f"{group}/{name}"))
            for path in sorted((CONF / "experiment").rglob("*.yaml")):
                experiment = path.relative_to(CONF / "experiment").with_suffix("").as_posix()
                name = (_raw(path).get("protocol") or {}).get("name") or compose(
                    "config", overrides=[f"experiment={experiment}"]).protocol.name
                found.append((path, PROTOCOLS.get(name).schema, "protocol", f"protocol/{name}"))
    finally:
        GlobalHydra.instance().clear()
    return found


def test_every_registered_schema_has_a_yaml(uses):
    registries = {**{group: group_registries()[group] for group in GROUPS}, "protocol": PROTOCOLS}
    covered = {entry for *_, entry in uses}
    missing = [f"{group}/{name}" for group, registry in registries.items() for name in registry.names()
               if f"{group}/{name}" not in covered]
    assert not missing, f"registered but used by no yaml: {missing}"
    assert "trainer" in covered


def _check(uses, protocols: bool) -> None:
    repeated = [message for path, schema, node, _ in uses if (node == "protocol") == protocols
                for message in repeated_defaults(path, schema, node)]
    assert not repeated, "write each default once, in the dataclass:\n" + "\n".join(repeated)


def test_no_group_yaml_repeats_a_default_of_its_schema(uses):
    _check(uses, protocols=False)


@pytest.mark.xfail("protocol" not in ConfigStore.instance().list("schema"), strict=True,
                   reason="the protocol schemas are not in Hydra's ConfigStore (schema/protocol/<name>) yet")
def test_no_experiment_repeats_a_default_of_its_protocol(uses):
    _check(uses, protocols=True)


def test_a_repeated_default_is_found(tmp_path, monkeypatch):
    """The check itself: a repeated default (also nested) fails, a difference, an interpolation or a reset of a
    parent's value passes."""
    conf = tmp_path / "conf"
    monkeypatch.setattr(sys.modules[__name__], "CONF", conf)
    (conf / "motion").mkdir(parents=True)
    parent, child = conf / "motion" / "parent.yaml", conf / "motion" / "child.yaml"
    parent.write_text("name: parent\nuse_labels: false\nndp:\n  hidden: 128\n  steps: 7\nlr: ${oc.env:LR,0.001}\n")
    child.write_text("defaults: [parent, _self_]\nname: child\nuse_labels: true\nkind: mlp\nndp: {mode: regression}\n")
    assert repeated_defaults(parent, SubgoalConfig) == [
        "conf/motion/parent.yaml: ndp.hidden=128 repeats the default of SubgoalConfig"]
    assert repeated_defaults(child, SubgoalConfig) == [  # use_labels: true resets the parent's false
        "conf/motion/child.yaml: ndp.mode='regression' repeats the default of SubgoalConfig"]
