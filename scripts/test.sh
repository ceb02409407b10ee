#!/usr/bin/env bash
# Install hecker_dynamics with its test dependencies into a fresh venv and run the suite.
#   bash scripts/test.sh                  # current numpy
#   bash scripts/test.sh --numpy 1.26.4   # pin numpy (1.26 is what ROS 2 Jazzy ships)
#   bash scripts/test.sh --installed      # the venv a run before made of this same tree
#                                         # (.ci/run, for its run without the kernel)
set -euo pipefail
cd "$(dirname "$0")/.."
numpy_pin=""
if [[ "${1:-}" == "--numpy" ]]; then numpy_pin="numpy==${2:?version}"; shift 2; fi
installed=""
if [[ "${1:-}" == "--installed" ]]; then installed=1; shift; fi
venv=".venv-test${numpy_pin:+-${numpy_pin#numpy==}}"
if [[ -n "$installed" && ! -x "$venv/bin/python" ]]; then
  echo "scripts/test.sh: --installed: no $venv yet; run bash scripts/test.sh first" >&2
  exit 2
elif [[ -z "$installed" ]]; then
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --upgrade pip
  "$venv/bin/python" -m pip install --quiet ".[test]" ${numpy_pin:+"$numpy_pin"}
fi
"$venv/bin/python" -c "import numpy; print('numpy', numpy.__version__)"
# -I and pytest's own script: the installed package is imported, not the source tree that
# `python -m pytest` would put first on sys.path, so the tests run the compiled kernel
# where pip built it (HECKER_DYNAMICS_KERNEL=0 in the environment switches it off);
# -n auto: one pytest-xdist worker per core.
kernel=$("$venv/bin/python" -I -c "import importlib.util as u
print('installed' if u.find_spec('hecker_dynamics._kernel') else 'not built')")
echo "compiled kernel: $kernel${HECKER_DYNAMICS_KERNEL:+ (HECKER_DYNAMICS_KERNEL=$HECKER_DYNAMICS_KERNEL)}"
"$venv/bin/pytest" -q -p no:cacheprovider -n auto "$@"
