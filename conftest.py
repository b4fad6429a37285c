"""Test-session set-up shared by every suite: DDS on loopback, composition-ready process.

Fast DDS reads its profile once per process, when the first participant is created, so
the profile that keeps in-process and DDS delivery apart must be in place before any test
calls ``rclpy.init`` (see efficient_comm.dds).
"""

import os

from efficient_comm.dds import prepare_process

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
prepare_process()
