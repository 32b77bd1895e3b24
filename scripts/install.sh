#!/usr/bin/env bash
# Create .venv and install hrc_lab (editable, with test tools) from this checkout's pyproject.toml.
# pip, not uv/poetry: pip reads the machine's local wheel folders (torch 2.14.1 lies on disk; uv/poetry would
# download a multi-GB CUDA build).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-$(command -v python3.11 || command -v python3)}
"$PYTHON" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
  || { echo "hrc_lab needs Python 3.11 (found $("$PYTHON" --version))" >&2; exit 1; }
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[dev,team]"
echo "installed: $(.venv/bin/python -c 'import hrc_lab, torch, torch_geometric, lightning, mlflow; print("hrc_lab", "torch", torch.__version__, "pyg", torch_geometric.__version__, "lightning", lightning.__version__, "mlflow", mlflow.__version__)' 2>/dev/null)"
