#!/usr/bin/env bash
# Set up, then run the soccer demo (a simulated humanoid plays: walks to the ball, kicks it at
# the goal). Arguments go to the demo: scripts/demo.sh --help
# With --robots N (2, 3, AvB such as 3v3) a team match instead: python -m humanoid_sim.match
# (--robots 1, or no --robots, is the one-robot demo).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh >&2
source scripts/env.sh
for arg in "$@"; do
    if [[ $arg == --robots || $arg == --robots=* ]]; then
        exec python -m humanoid_sim.match "$@"
    fi
done
exec python -m humanoid_sim.demo "$@"
