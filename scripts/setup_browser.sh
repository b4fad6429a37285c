#!/usr/bin/env bash
# Install what the browser tests of debug_gui drive: Debian's chromium and the chromedriver
# built for it (selenium talks to it; matching versions come from one Debian release), and
# the viewers' own client library from npm (tests/foxglove_viewer: the Foxglove WebSocket
# client and ROS 2 decoder the Foxglove and Lichtblick apps are built on).
# Idempotent: does nothing when all are there.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_apt.sh"

packages=(chromium chromium-driver)

have_all() {
  command -v chromium >/dev/null && command -v chromedriver >/dev/null
}

apt_ensure setup_browser have_all "${packages[@]}"

viewer=$(cd "$(dirname "${BASH_SOURCE[0]}")/../tests/foxglove_viewer" && pwd)
stamp=$(sha256sum "$viewer/package-lock.json" | cut -d' ' -f1)
if [[ $(cat "$viewer/node_modules/.lock-stamp" 2>/dev/null) != "$stamp" ]]; then
  if ! command -v npm >/dev/null; then
    echo "setup_browser: npm missing: install node.js (20 or later) and npm" >&2
    exit 1
  fi
  echo "setup_browser: npm ci in tests/foxglove_viewer"
  (cd "$viewer" && npm ci --no-audit --no-fund --loglevel=error)
  echo "$stamp" >"$viewer/node_modules/.lock-stamp"
fi
