#!/usr/bin/env bash
# Regenerate the golden bags in test/golden/ (see test/golden/README.md).
#
# For every shipped scene (hecker_dynamics.scene.load.shipped_scenes()), writes
#   test/golden/<scene>/input    the scene's scripted inputs   (hecker-dynamics script)
#   test/golden/<scene>/output   the replayed node outputs     (hecker-dynamics replay)
# as rosbag2 bags in mcap storage with zstd-compressed chunks, over the first
# GOLDEN_DURATION seconds of sim time (default 4; shorter scenes keep their own duration).
# Bags of scenes that are no longer shipped are removed.
#
#   bash scripts/make_golden_bags.sh                      # with python3 on PATH
#   PYTHON=/work/venv/bin/python bash scripts/make_golden_bags.sh
set -euo pipefail
cd "$(dirname "$0")/.."
python="${PYTHON:-python3}"
export GOLDEN_DURATION="${GOLDEN_DURATION:-4}"
# Use this source tree, not an installed copy.
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
cli=("$python" -m hecker_dynamics.cli)

# "<scene> <seconds>" per shipped scene: the golden length, capped by the scene's duration
# and, for scenes of many bodies, by GOLDEN_ENTRIES entries of the outputs (per publish
# instant a pose, a twist and a /tf transform per body and a joint state per joint), which
# keeps the bags small (each topic adds a fixed part: its metadata, schema and index).
plan=$("$python" - <<'PY'
import os
from hecker_dynamics.scene.load import load_scene, shipped_scenes
cap_ns = round(float(os.environ["GOLDEN_DURATION"]) * 1e9)
budget = int(os.environ.get("GOLDEN_ENTRIES", "3000"))
for name in shipped_scenes():
    scene = load_scene(name)
    instants = max(1, budget // (3 * len(scene.bodies) + len(scene.joints)))
    ns = min(scene.duration_ns, cap_ns, instants * scene.publish_period_ns)
    print(name, f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}")
PY
)
[[ -n "$plan" ]] || { echo "make_golden_bags: no shipped scenes found" >&2; exit 1; }

mkdir -p test/golden
shipped=()
while read -r scene seconds; do
    shipped+=("$scene")
    dir="test/golden/$scene"
    rm -rf "$dir"
    mkdir -p "$dir"
    "${cli[@]}" script "$scene" -o "$dir/input" --duration "$seconds" --compress
    "${cli[@]}" replay "$scene" "$dir/input" -o "$dir/output" --compress --no-progress
done <<< "$plan"

# Drop golden bags of scenes that are no longer shipped.
for dir in test/golden/*/; do
    name=$(basename "$dir")
    if [[ -d "$dir/input" || -d "$dir/output" ]] && [[ ! " ${shipped[*]} " =~ " $name " ]]; then
        echo "removing golden bags of $name (no longer shipped)"
        rm -rf "$dir"
    fi
done
du -sh test/golden/*/ | sed 's/^/golden bags: /'
