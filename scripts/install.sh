#!/usr/bin/env bash
# Create .venv and install hrc_lab (editable, with test and documentation tools) from this checkout's pyproject.toml.
# pip, not uv/poetry: pip reads the machine's local wheel folders (torch 2.14.1 lies on disk; uv/poetry would
# download a multi-GB CUDA build).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-$(command -v python3.11 || command -v python3)}
"$PYTHON" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
  || { echo "hrc_lab needs Python 3.11 (found $("$PYTHON" --version))" >&2; exit 1; }
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
# Timings below: a fresh clone on 2 cores, 2026-12-02 (docs/getting-started.md).
# pip 26.3: resolves this project's ~150 requirements in 44 s where the pip that venv bundles (23.2.1) takes 92 s.
.venv/bin/python -m pip install --quiet --disable-pip-version-check "pip==26.3"
# --no-compile: pip would byte-compile all ~22,000 modules of the environment (~150 s); instead the import below
# compiles the ~6,000 a run imports. It writes them even where PYTHONDONTWRITEBYTECODE is set (as on these
# machines), so that no later process compiles them again (the quick table: 151 s without them, 111 s with them).
.venv/bin/python -m pip install --quiet --disable-pip-version-check --no-compile -e ".[dev,team,docs]"
env -u PYTHONDONTWRITEBYTECODE .venv/bin/python - <<'PY'
import importlib, pkgutil, warnings
warnings.simplefilter("ignore")
import hrc_lab
for module in pkgutil.walk_packages(hrc_lab.__path__, "hrc_lab."):  # every module of hrc_lab imports
    importlib.import_module(module.name)
# what hrc_lab imports inside functions, and the test runner
for name in ("lightning.pytorch", "mlflow.tracking", "matplotlib.pyplot", "sklearn.gaussian_process", "cv2",
             "mediapipe", "robosuite", "psycopg", "gymnasium_robotics", "pytest"):
    importlib.import_module(name)
import lightning, mlflow, torch, torch_geometric
print("installed: hrc_lab torch", torch.__version__, "pyg", torch_geometric.__version__, "lightning",
      lightning.__version__, "mlflow", mlflow.__version__)
PY
