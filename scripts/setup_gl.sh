#!/usr/bin/env bash
# Install what the simulator's offscreen camera renders with on a machine without display or
# GPU: Mesa's EGL (first choice) and OSMesa (the fallback). Idempotent: does nothing when
# both libraries are already there.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_apt.sh"

packages=(libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6)

have_all() {
  # Not `ldconfig -p | grep -q`: grep leaving early can kill ldconfig with SIGPIPE, which
  # pipefail turns into "missing".
  local libs
  libs=$(ldconfig -p)
  grep -q 'libEGL_mesa\.so\.0' <<<"$libs" && grep -q 'libOSMesa\.so' <<<"$libs"
}

apt_ensure setup_gl have_all "${packages[@]}"
