#!/usr/bin/env bash
# Set up the project from PyPI wheels (no ROS apt install needed): make .venv/ with ROS 2 Jazzy
# and the dev tools, then build the colcon workspace ros2_ws/ into ros2_ws/{build,install,log}.
# Idempotent: re-running only reinstalls when tools/requirements.txt or the constraints changed.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
root=$PWD
venv=$root/.venv

# One set-up at a time per checkout: pip and colcon write the same trees.
exec 9>"$root/.setup.lock"
flock 9

if [[ ! -x $venv/bin/python ]]; then
  echo "setup: creating .venv"
  python3.11 -m venv "$venv"
fi

stamp=$(cat tools/requirements.txt tools/constraints-jazzy.txt | sha256sum | cut -d' ' -f1)
if [[ $(cat "$venv/.requirements-stamp" 2>/dev/null) != "$stamp" ]]; then
  echo "setup: installing tools/requirements.txt (log: .venv/pip-install.log)"
  if ! "$venv/bin/python" -m pip install -c tools/constraints-jazzy.txt -r tools/requirements.txt \
      >"$venv/pip-install.log" 2>&1; then
    grep -v "is ignored" "$venv/pip-install.log" | tail -n 40 >&2
    echo "setup: pip install failed" >&2
    exit 1
  fi
  echo "$stamp" >"$venv/.requirements-stamp"
else
  echo "setup: requirements up to date"
fi

"$venv/bin/python" scripts/fix_wheel_cmake_paths.py
bash scripts/setup_gl.sh  # the simulator's offscreen camera (EGL, OSMesa)

# The `ros2` command (ros2_pip_cli): ros2cli has no wheels, so the venv gets a launcher of its
# own. Only the venv: on a regular ROS 2 install nothing shadows the real ros2cli. It finds the
# package through PYTHONPATH, i.e. whatever workspace `source scripts/env.sh` sourced.
launcher=$(cat <<'LAUNCHER'
#!/usr/bin/env bash
# Written by scripts/setup.sh: the ros2 command of the pip install (ros2_pip_cli), venv only.
exec "$(dirname "$0")/python" -c 'import sys
try:
    from ros2_pip_cli import main
except ImportError as exc:
    sys.exit(f"ros2: {exc}: source scripts/env.sh first (it puts the workspace on the paths)")
sys.exit(main())' "$@"
LAUNCHER
)
if [[ $(cat "$venv/bin/ros2" 2>/dev/null) != "$launcher" ]]; then
  printf '%s\n' "$launcher" >"$venv/bin/ros2"
  chmod +x "$venv/bin/ros2"
  echo "setup: wrote $venv/bin/ros2"
fi

echo "setup: building ros2_ws"
# CMake finds rosidl typesupports through both paths. colcon then warns that .venv has no
# local_setup.* files: expected, the wheels' prefix is not a colcon workspace.
export PATH=$venv/bin:$PATH VIRTUAL_ENV=$venv
export AMENT_PREFIX_PATH=$venv CMAKE_PREFIX_PATH=$venv
cd ros2_ws
colcon --log-base log build --symlink-install --base-paths src --metas "$root/colcon.meta"
