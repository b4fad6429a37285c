"""Make the test process composition-ready, also when run by ``colcon test`` alone.

Fast DDS reads its profile when the process creates its first participant, so the profile
that keeps in-process and DDS delivery apart must be set before any test calls rclpy.init.
"""

import os

from efficient_comm.dds import prepare_process

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
prepare_process()
