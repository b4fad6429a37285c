#!/usr/bin/env bash
# Install the ROS 1 system rf_bridge's tests run against: Debian's ROS 1 packages
# (rosmaster, rospy, rostopic, rosbag and the common message packages for the system
# python3). Idempotent: does nothing when everything is already there.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_apt.sh"

packages=(
  python3-rosmaster python3-rospy python3-rostopic python3-rosbag
  python3-std-msgs python3-geometry-msgs python3-sensor-msgs python3-nav-msgs
)

have_all() {
  command -v rosmaster >/dev/null && command -v rostopic >/dev/null \
    && command -v rosbag >/dev/null \
    && /usr/bin/python3 -c 'import rospy, rosbag, std_msgs.msg, geometry_msgs.msg, sensor_msgs.msg, nav_msgs.msg' \
      >/dev/null 2>&1
}

apt_ensure setup_ros1 have_all "${packages[@]}"
