#!/usr/bin/env bash
# ruff on the tree and mypy (--strict) on the whole package, as pyproject.toml configures
# them, in a venv of their own (.venv-lint: the package with its `lint` extra), apart from
# the test venvs.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=".venv-lint"
[[ -x "$venv/bin/python" ]] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --upgrade pip
"$venv/bin/python" -m pip install --quiet ".[lint]"
"$venv/bin/ruff" --version
"$venv/bin/ruff" check hecker_dynamics test setup.py
"$venv/bin/mypy" --version
"$venv/bin/mypy"
