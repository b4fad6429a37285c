"""A short lockstep run of the whole soccer robot; prints what a run's outcome is made of.

``python tests/_lockstep_run.py SECONDS SEED LINE_NOISE``: one JSON line with the driver's
bus errors, the emulator's counters and the final joint positions and ball, to compare runs
made at different machine loads (tests/test_lockstep_load_sil.py).
"""

from __future__ import annotations

import json
import sys

from efficient_comm import Container, ManualClock
from humanoid_sim.soccer.compose import compose


def main() -> None:
    seconds, seed, noise = float(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    with Container("lockstep_run", dds=False, clock=ManualClock()) as container:
        robot = compose(container, simulator={"seed": seed, "line_noise": noise,
                                              "robot_pose": [-1.0, 0.5, 0.0],
                                              "ball_position": [0.0, 0.0]})
        container.advance(seconds)
        sim = robot.simulator
        print(json.dumps({
            "comm_errors": robot.driver.comm_errors,
            "present": sorted(robot.driver.present),
            "bus_packets": sim.pty.bus.packets,
            "crc_errors": sim.pty.bus.crc_errors,
            "discarded_bytes": sim.pty.discarded_bytes,
            "dropped_replies": sim.pty.dropped_replies,
            "qpos": [round(float(v), 9) for v in sim.data.qpos],
        }), flush=True)


if __name__ == "__main__":
    main()
