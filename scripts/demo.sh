#!/usr/bin/env bash
# Set up, then run the efficient_comm demo. Arguments go to the demo: scripts/demo.sh --help
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh >&2
source scripts/env.sh
exec python -m efficient_comm.examples.demo "$@"
