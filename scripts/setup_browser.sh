#!/usr/bin/env bash
# Install what the browser tests of debug_gui drive: Debian's chromium and the chromedriver
# built for it (selenium talks to it; matching versions come from one Debian release).
# Idempotent: does nothing when both are there.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_apt.sh"

packages=(chromium chromium-driver)

have_all() {
  command -v chromium >/dev/null && command -v chromedriver >/dev/null
}

apt_ensure setup_browser have_all "${packages[@]}"
