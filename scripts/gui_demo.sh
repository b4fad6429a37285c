#!/usr/bin/env bash
# Set up, then run a team match (python -m humanoid_sim.match) and the debugging GUI watching
# its robots; open the URL it prints. Arguments go to the demo: scripts/gui_demo.sh --help
# (--robots 1v1 a lighter match; --solo robots that each play alone).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh >&2
source scripts/env.sh
exec python -m debug_gui.demo "$@"
