"""Shared fixtures: compose the real configs (shrinking sizes, not behaviour) and keep every output in tmp_path."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra

# Off-screen MuJoCo rendering (the Ch.6 clutter scenes) must be chosen before the first `import mujoco`, which an
# earlier test may do through robosuite.
os.environ.setdefault("MUJOCO_GL", "egl")

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"


@pytest.fixture
def compose_config(tmp_path, monkeypatch):
    """compose_config(*overrides) -> the composed DictConfig, with runs/ redirected to tmp_path."""
    monkeypatch.setenv("HRC_LAB_RUNS", str(tmp_path / "runs"))

    def _compose(*overrides: str):
        GlobalHydra.instance().clear()
        with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
            return compose("config", overrides=list(overrides), return_hydra_config=False)

    yield _compose
    GlobalHydra.instance().clear()


@pytest.fixture
def cli_env(tmp_path):
    """Environment for running the console scripts with all outputs under tmp_path."""
    env = dict(os.environ, HRC_LAB_RUNS=str(tmp_path / "runs"), PYTHONWARNINGS="ignore")
    return env


@pytest.fixture(scope="session")
def console_script():
    """console_script(name) -> path of an installed console script (hrc-lab, hrc-lab-report) beside the running
    interpreter, so the tests work without an activated venv."""
    return lambda name: str(Path(sys.executable).with_name(name))
