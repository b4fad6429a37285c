#!/usr/bin/env bash
# Set up, then run benchmarks with the venv's python: the bench/*.py files given, or all of them
# (files starting with "_" are helpers and are skipped). scripts/bench.sh bench/latency.py
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh >&2
source scripts/env.sh
shopt -s nullglob
benches=("$@")
((${#benches[@]})) || benches=(bench/[!_]*.py)
((${#benches[@]})) || { echo "bench: no bench/*.py to run" >&2; exit 1; }
for b in "${benches[@]}"; do
  echo "bench: $b" >&2
  python "$b"
done
