#!/usr/bin/env bash
# Install the ROS 1 system rf_bridge's tests run against: Debian's ROS 1 packages
# (rosmaster, rospy, rostopic, rosbag and the common message packages for the system
# python3). Idempotent: does nothing when everything is already there.
set -euo pipefail

packages=(
  python3-rosmaster python3-rospy python3-rostopic python3-rosbag
  python3-std-msgs python3-geometry-msgs python3-sensor-msgs
)

have_all() {
  command -v rosmaster >/dev/null && command -v rostopic >/dev/null \
    && command -v rosbag >/dev/null \
    && /usr/bin/python3 -c 'import rospy, rosbag, std_msgs.msg, geometry_msgs.msg, sensor_msgs.msg' \
      >/dev/null 2>&1
}

if have_all; then
  exit 0
fi
if ((EUID != 0)); then
  echo "setup_ros1: the ROS 1 packages are missing and installing them needs root:" >&2
  echo "  apt-get install ${packages[*]}" >&2
  exit 1
fi
echo "setup_ros1: installing Debian's ROS 1 packages"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null
have_all || { echo "setup_ros1: ROS 1 still incomplete after install" >&2; exit 1; }
