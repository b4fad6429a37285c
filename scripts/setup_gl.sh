#!/usr/bin/env bash
# Install what the simulator's offscreen camera renders with on a machine without display or
# GPU: Mesa's EGL (first choice) and OSMesa (the fallback). Idempotent: does nothing when
# both libraries are already there.
set -euo pipefail

packages=(libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6)

have_all() {
  # Not `ldconfig -p | grep -q`: grep leaving early can kill ldconfig with SIGPIPE, which
  # pipefail turns into "missing".
  local libs
  libs=$(ldconfig -p)
  grep -q 'libEGL_mesa\.so\.0' <<<"$libs" && grep -q 'libOSMesa\.so' <<<"$libs"
}

if have_all; then
  exit 0
fi
if ((EUID != 0)); then
  echo "setup_gl: offscreen OpenGL libraries are missing and installing them needs root:" >&2
  echo "  apt-get install ${packages[*]}" >&2
  exit 1
fi
echo "setup_gl: installing Mesa EGL and OSMesa"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null
have_all || { echo "setup_gl: EGL/OSMesa still missing after install" >&2; exit 1; }
