"""A short lockstep run of the whole soccer robot; prints what a run's outcome is made of.

``python tests/_lockstep_run.py SECONDS SEED LINE_NOISE [--slow-emulator MS] [--look-late]``:
one JSON line with the driver's bus errors, the emulator's counters and the final joint
positions and ball, to compare runs made at different machine loads
(tests/test_lockstep_load_sil.py).

Two options stand for a loaded machine without needing one, each at a point where a
lockstep run once depended on the wall clock: ``--slow-emulator MS`` makes the emulator's
thread take MS before it handles each packet (as when busy processes leave it little CPU);
``--look-late`` waits until the emulator has handled every byte sent to it
(``PtyBus.sync``) before the counters are read (as when the main thread is the one held
up). Neither may change what the run prints.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

from efficient_comm import Container, ManualClock
from humanoid_sim.dynamixel.protocol import Packet
from humanoid_sim.soccer.compose import compose


def slowed(handle: Callable[[Packet], bytes], delay_s: float) -> Callable[[Packet], bytes]:
    """``handle``, each call delayed by ``delay_s``: a fault injected into the emulator."""
    def handle_late(packet: Packet) -> bytes:
        time.sleep(delay_s)
        return handle(packet)
    return handle_late


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("seconds", type=float)
    parser.add_argument("seed", type=int)
    parser.add_argument("line_noise", type=float)
    parser.add_argument("--slow-emulator", type=float, default=0.0, metavar="MS")
    parser.add_argument("--look-late", action="store_true")
    args = parser.parse_args()
    with Container("lockstep_run", dds=False, clock=ManualClock()) as container:
        robot = compose(container, simulator={"seed": args.seed, "line_noise": args.line_noise,
                                              "robot_pose": [-1.0, 0.5, 0.0],
                                              "ball_position": [0.0, 0.0]})
        sim = robot.simulator
        bus = sim.pty.bus
        if args.slow_emulator:
            delayed = slowed(bus.handle, args.slow_emulator / 1000)
            bus.handle = delayed  # type: ignore[method-assign,assignment]
        container.advance(args.seconds)
        if args.look_late:
            sim.pty.sync()
        print(json.dumps({
            "comm_errors": robot.driver.comm_errors,
            "present": sorted(robot.driver.present),
            "bus_packets": bus.packets,
            "crc_errors": bus.crc_errors,
            "sent_bytes": sim.pty.sent_bytes,
            "discarded_bytes": sim.pty.discarded_bytes,
            "dropped_replies": sim.pty.dropped_replies,
            "qpos": [round(float(v), 9) for v in sim.data.qpos],
        }), flush=True)


if __name__ == "__main__":
    main()
