#!/usr/bin/env bash
# Set up, then run the soccer demo (a simulated humanoid plays: walks to the ball, kicks it at
# the goal). Arguments go to the demo: scripts/demo.sh --help
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh >&2
source scripts/env.sh
exec python -m humanoid_sim.demo "$@"
