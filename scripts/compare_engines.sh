#!/usr/bin/env bash
# Measure the distributed engines the sweep could use (docs/batch.md, "Choosing the engine"):
# install weight and time, start-up of a 2-worker local cluster, per-task overhead.
#   bash scripts/compare_engines.sh [ROUNDS]    # default 3 rounds, medians
# Each engine goes into a throwaway venv under a temporary directory (removed at the end).
set -euo pipefail
rounds="${1:-3}"
here="$(cd "$(dirname "$0")" && pwd)"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
declare -A requirement=([dask]="dask[distributed]" [ray]="ray")
for engine in dask ray; do
  venv="$scratch/$engine"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --upgrade pip
  "$venv/bin/python" -m pip install --quiet numpy  # the project's own, not the engine's
  before=$(du -sk "$venv" | cut -f1)
  started=$(date +%s.%N)
  "$venv/bin/python" -m pip install --quiet "${requirement[$engine]}"
  seconds=$(python3 -c "print(f'{$(date +%s.%N) - $started:.1f}')")
  after=$(du -sk "$venv" | cut -f1)
  version=$("$venv/bin/python" -m pip show "${engine/dask/distributed}" | sed -n 's/^Version: //p')
  echo "$engine $version: install ${seconds} s, $(( (after - before) / 1024 )) MB"
done
# Interleaved: a round of each engine in turn; medians over the rounds.
for round in $(seq "$rounds"); do
  for engine in dask ray; do
    "$scratch/$engine/bin/python" "$here/compare_engines.py" "$engine" 2>/dev/null >> "$scratch/rounds"
  done
done
python3 - "$scratch/rounds" "$rounds" <<'PY'
import collections, statistics, sys
values = collections.defaultdict(list)
for line in open(sys.argv[1]):
    name, value = line.rstrip("\n").split("\t")
    values[name].append(float(value))
for name, found in values.items():
    print(f"{name}: median {statistics.median(found):.3g} of {len(found)} "
          f"(min {min(found):.3g}, max {max(found):.3g})")
PY
