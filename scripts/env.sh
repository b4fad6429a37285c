# Source this file from bash (`source scripts/env.sh`) for a shell with .venv activated and the
# built workspace ros2_ws/install on the paths. scripts/setup.sh creates both.
_ec_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [[ ! -f $_ec_root/ros2_ws/install/setup.bash ]]; then
  echo "env.sh: $_ec_root/ros2_ws/install/setup.bash missing; run scripts/setup.sh first" >&2
  return 1
fi
# The venv's activate and colcon's setup.bash read unset variables: relax `set -u` around them.
case $- in *u*) _ec_nounset=1 ;; *) _ec_nounset= ;; esac
set +u
source "$_ec_root/.venv/bin/activate"
# The wheels' prefix (.venv) holds the ament index of rclpy and the messages; colcon's
# setup.bash does not chain it, so add it here once.
case ":${AMENT_PREFIX_PATH:-}:" in
  *":$VIRTUAL_ENV:"*) ;;
  *) export AMENT_PREFIX_PATH=$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH} ;;
esac
source "$_ec_root/ros2_ws/install/setup.bash"
if [[ -n $_ec_nounset ]]; then set -u; fi
export ROS_AUTOMATIC_DISCOVERY_RANGE=${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}
# One OpenBLAS thread per process unless set: a robot is many small Python processes, whose
# matrices are too small to gain from threads, and numpy's import starting OpenBLAS's pool
# cost about 0.1 s of CPU in every one of them (0.36 against 0.25 s for `import numpy`).
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}
unset _ec_root _ec_nounset
