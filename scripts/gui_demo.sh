#!/usr/bin/env bash
# Set up, then run three simulated robots and the debugging GUI watching them; open the URL it
# prints. Arguments go to the demo: scripts/gui_demo.sh --help
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh >&2
source scripts/env.sh
exec python -m debug_gui.demo "$@"
