"""What a team match records, on which clocks, and the merged log and video it leaves.

Each robot runs on a clock of its own, deliberately off the world's as a separate computer's
is (:func:`clock_skews`: an offset and a drift per robot, drawn from the match's seed), and
measures that offset with team_clock's ``ClockSync`` against the world, the team's reference
clock: the world answers on every robot's domain (:class:`ClockServers`), as the one
computer whose time the robots synchronise to. Each robot's recorder stores its estimates
with its bag (:func:`add_robot_recording`, :data:`ROBOT_TOPICS`); the world records the
ground truth and the referee on its own clock (:func:`world_topics`). At the end
:func:`merge_recordings` puts them into one MCAP in the world's time through
:func:`~.match_log.merge_match`. The external video (:mod:`.match_video`) is filmed on a
camera clock of its own (:func:`clock_skews` ``["camera"]``).

Where everything goes (:func:`recording_paths`), under the match's ``--out-dir``, one
``<run>`` (UTC date and time) per match so that nothing of an earlier match is overwritten:
``bags/<run>/<robot>/`` and ``bags/<run>/world/`` (each a recorder's bag directory),
``merged_<run>/`` (the merged bag), ``video_<run>.mp4`` with ``video_<run>.mp4.json`` (its
sidecar: start time and calibration) and ``video_<run>.truth.json`` (the camera clock's
true offset and drift, for checking what the offline tools find).
"""

from __future__ import annotations

import json
import random
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from efficient_comm import Container
from efficient_comm.handle import Clock
from robot_recorder import Recorder
from team_clock import MergeReport, SkewedClock, TeamClockError

from .match_log import WORLD, merge_match

__all__ = ["CLOCK_TRUTH", "ROBOT_TOPICS", "ClockServers", "ClockSkew", "ClockSyncThread",
           "RecordingPaths",
           "add_robot_recording", "clock_skews", "merge_recordings", "recording_paths",
           "recording_report", "world_topics"]

#: What each robot records on board (relative names are under the robot's namespace). Images
#: as JPEG with the ball detector's drawing at 2 Hz (the compressor encodes only what is
#: asked for), joint states and IMU thinned: about 40 kB/s a robot, not the camera's 9 MB/s.
ROBOT_TOPICS = [
    "camera/image_raw/compressed max_rate_hz=2", "ball/debug_markers max_rate_hz=2",
    "efficient_comm/stats", "/rosout", "/diagnostics",
    "localization/pose", "ball/detection", "ball/estimate", "ball/position", "team_ball",
    "role", "behaviour/state", "fall/state", "motion/state", "cmd_vel", "team/messages",
    "game_state", "ground_truth/pose", "ground_truth/ball",
    "joint_states max_rate_hz=10", "imu/data max_rate_hz=20",
]
#: Beside a robot's bag: its clock's true offset, drift and epoch (for tests, never the fit).
CLOCK_TRUTH = "clock_truth.json"
#: Where a robot's own estimates are recorded from (relative: under its namespace).
LOCAL_OFFSET_TOPIC = "team_clock/offset"
#: The GIL's switch interval in a process with a clock sync (s; see ClockSyncThread).
SWITCH_INTERVAL_S = 0.0005
#: How often a robot's ClockSync exchanges with the world (s).
SYNC_PERIOD_S = 0.25


def world_topics(robots: Sequence[str]) -> list[str]:
    """What the world records: every robot's ground truth, the ball's and the referee's."""
    return ([f"/ground_truth/{robot}/pose" for robot in robots]
            + ["/ground_truth/ball", "/game_state"])


@dataclass(frozen=True, slots=True)
class ClockSkew:
    """A clock ``offset_s`` ahead of the world's, running ``drift_ppm`` fast."""

    offset_s: float
    drift_ppm: float


def clock_skews(robots: Sequence[str], seed: int) -> dict[str, ClockSkew]:
    """Each robot's clock, and the video camera's (``"camera"``), for ``seed``.

    Robots: 0.1 to 0.8 s either way and 5 to 50 ppm either way (computers without NTP);
    the camera: 1 to 4 s either way and up to 20 ppm (a camera's clock set by hand).
    """
    rng = random.Random(f"soccer match clocks {seed}")

    def signed(low: float, high: float) -> float:
        return rng.choice((-1.0, 1.0)) * rng.uniform(low, high)

    skews = {robot: ClockSkew(round(signed(0.1, 0.8), 6), round(signed(5.0, 50.0), 3))
             for robot in robots}
    skews["camera"] = ClockSkew(round(signed(1.0, 4.0), 6), round(signed(0.0, 20.0), 3))
    return skews


@dataclass(frozen=True, slots=True)
class RecordingPaths:
    """Where one match's recordings go (see the module docstring)."""

    bags: Path
    merged: Path
    video: Path
    video_truth: Path

    def bag_dir(self, process: str) -> Path:
        """A robot's (or the world's) recorder's ``output_dir``."""
        return self.bags / process


def recording_paths(out_dir: Path, run: str) -> RecordingPaths:
    return RecordingPaths(bags=out_dir / "bags" / run, merged=out_dir / f"merged_{run}",
                          video=out_dir / f"video_{run}.mp4",
                          video_truth=out_dir / f"video_{run}.truth.json")


def add_robot_recording(container: Container, namespace: str, *, robot: str,
                        bag_dir: Path, clock_sync: bool = True
                        ) -> tuple[Recorder, ClockSyncThread | None]:
    """The robot's clock sync against the world (:class:`ClockSyncThread`, on the
    container's clock) and its recorder, recording at once; close the thread at the end.

    ``clock_sync=False`` (a lockstep match: the robot runs on the world's simulated time,
    there is no offset to measure): the recorder alone, and the merge takes the log as it
    is (:func:`merge_recordings`)."""
    from team_clock.sync import OFFSET_QOS
    from team_clock_interfaces.msg import ClockOffset

    # The estimates reach the recorder in-process, under the robot's namespace: from DDS
    # they waited in the container's executor, and the recorder got 5 of 70 (team_clock
    # reads estimates from any ``<namespace>/team_clock/offset``).
    estimates = container.add(lambda node: node, name="clock_estimates", namespace=namespace)
    local = estimates.create_publisher(ClockOffset, LOCAL_OFFSET_TOPIC, qos=OFFSET_QOS)
    clock = container.executor.clock
    if isinstance(clock, SkewedClock):  # the truth, for tests of the alignment
        bag_dir.mkdir(parents=True, exist_ok=True)
        (bag_dir / CLOCK_TRUTH).write_text(json.dumps({
            "offset_ns": clock.offset_ns, "drift_ppm": clock.drift_ppm,
            "epoch_ns": clock.epoch_ns,
            "doc": "local = world + offset_ns + drift_ppm*1e-6*(world - epoch_ns)"}) + "\n")
    sync = ClockSyncThread(robot=robot, reference=WORLD, namespace=namespace, clock=clock,
                           on_estimate=local.publish) if clock_sync else None
    try:
        recorder: Recorder = container.add(
            Recorder, name="recorder", namespace=namespace,
            parameters={"topics": ROBOT_TOPICS, "output_dir": str(bag_dir),
                        "autostart": True, "clock_robot": robot,
                        "clock_topic": LOCAL_OFFSET_TOPIC})
    except BaseException:
        if sync is not None:
            sync.close()
        raise
    return recorder, sync


class ClockSyncThread:
    """team_clock's ``ClockSync`` in a small container and thread of its own, on ``clock``.

    Why not in the robot's container: its executor takes DDS samples between its timers,
    and under load a pong waited there longer than the exchange's timeout (a robot of the
    match got 1 sample of 30 pings). Here the exchange only waits for the GIL, and the
    clock read is the robot's own (the same clock object as its container's). The world
    runs one per robot domain as the reference (``robot == reference``): it answers with
    its time and measures nothing.
    """

    def __init__(self, *, robot: str, reference: str, namespace: str, clock: Clock,
                 domain_id: int | None = None,
                 on_estimate: Callable[[Any], None] | None = None) -> None:
        """``on_estimate`` gets each of this robot's estimates (a ``ClockOffset``), in
        this thread."""
        from team_clock.sync import OFFSET_QOS, OFFSET_TOPIC, ClockSync
        from team_clock_interfaces.msg import ClockOffset

        # A thread waiting for the GIL waits up to the switch interval (5 ms by default)
        # while the process's main thread computes, and an exchange's timestamps carry
        # that wait, more on one way than the other: the match's offsets were biased by 2
        # to 5 ms under load. Process-wide, so the world's and every robot's alike.
        sys.setswitchinterval(min(sys.getswitchinterval(), SWITCH_INTERVAL_S))

        self._container = Container(f"{namespace.strip('/') or 'root'}_clock", dds=True,
                                    domain_id=domain_id, serve=False, stats_period_s=0,
                                    clock=clock)
        try:
            self.sync: ClockSync = self._container.add(
                ClockSync, name="clock_sync", namespace=namespace,
                parameters={"robot": robot, "reference": reference,
                            "period_s": SYNC_PERIOD_S})
            if on_estimate is not None:
                forward = on_estimate
                tap = self._container.add(lambda node: node, name="clock_tap",
                                          namespace=namespace)
                tap.create_subscription(
                    ClockOffset, OFFSET_TOPIC,
                    lambda msg: forward(msg) if msg.robot == robot else None, qos=OFFSET_QOS)
        except BaseException:
            self._container.close()
            raise
        self._thread = threading.Thread(target=self._container.executor.spin, daemon=True,
                                        name=f"clock sync {robot}")
        self._thread.start()

    def close(self) -> None:
        """Stop; the participant leaves its domain. A second call does nothing."""
        if self._thread.is_alive():
            self._container.shutdown()
            self._thread.join(timeout=5)
            self._container.close()


class ClockServers:
    """The world's clock as the team's reference, answering on every robot's domain: one
    :class:`ClockSyncThread` per robot domain whose robot is the reference, on ``clock``
    (the world's container's: the clock its ground truth is stamped with)."""

    def __init__(self, domains: Mapping[str, int], *, clock: Clock) -> None:
        self._servers: list[ClockSyncThread] = []
        try:
            for robot, domain in domains.items():
                self._servers.append(ClockSyncThread(
                    # A namespace per robot domain: rosout keeps one logger per node
                    # name and process.
                    robot=WORLD, reference=WORLD, namespace=f"/{WORLD}_for_{robot}",
                    clock=clock, domain_id=domain))
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop answering; every participant leaves its domain."""
        for server in self._servers:
            server.close()
        self._servers.clear()


def newest_bag(directory: Path) -> Path | None:
    """The bag a recorder wrote under ``directory`` (its newest, if it wrote several)."""
    bags = sorted((p for p in directory.glob("*") if p.is_dir() and any(p.glob("*.mcap"))),
                  key=lambda p: p.stat().st_mtime)
    return bags[-1] if bags else None


def merge_recordings(paths: RecordingPaths, robots: Sequence[str], *,
                     lockstep: bool = False) -> tuple[MergeReport | None, str]:
    """Merge the robots' and the world's bags into ``paths.merged``; the report's line.

    Log times are aligned; header stamps are left as recorded: ground truth and the game
    state carry the world's time, what the robot measured (camera, IMU, joints, its
    estimates) its own clock's. A robot without a bag (its process died before recording)
    is left out and named. ``lockstep``: every robot ran on the world's simulated time,
    so its log is merged as it is.
    """
    world = newest_bag(paths.bag_dir(WORLD))
    if world is None:
        return None, f"no merged log: the world recorded nothing ({paths.bag_dir(WORLD)})"
    bags = {robot: newest_bag(paths.bag_dir(robot)) for robot in robots}
    missing = sorted(robot for robot, bag in bags.items() if bag is None)
    try:
        report = merge_match({r: b for r, b in bags.items() if b is not None}, world,
                             paths.merged, stamps=False,
                             on_world_time=robots if lockstep else ())
    except (TeamClockError, OSError) as exc:
        return None, f"no merged log: {exc}"
    offsets = ", ".join(f"{r.namespace} ±{r.max_uncertainty_ns / 1e6:.2f} ms"
                        for r in report.robots if r.namespace != WORLD)
    line = (f"merged log {report.output}: {report.messages} messages in the world's time "
            f"(clock offsets measured to {offsets})")
    if missing:
        line += f"; no bag from {', '.join(missing)}"
    return report, line


def recording_report(paths: RecordingPaths, skews: Mapping[str, ClockSkew], merge_line: str,
                     *, video: bool) -> str:
    """The match report's part on recordings: the clocks as drawn, the merged log, the video."""
    clocks = ", ".join(f"{name} {s.offset_s * 1e3:+.0f} ms {s.drift_ppm:+.1f} ppm"
                       for name, s in skews.items() if name != "camera")
    lines = [f"Clocks (true offset from the world's, drift): {clocks}; robots' bags in "
             f"{paths.bags}.", "", merge_line + ".", ""]
    if video:
        camera = skews["camera"]
        state = "written" if paths.video.exists() else "NOT written (see world.log)"
        lines += [f"External video {paths.video} {state}, on a camera clock "
                  f"{camera.offset_s:+.3f} s {camera.drift_ppm:+.1f} ppm off the world's "
                  f"(sidecar {paths.video}.json; the truth for tests in "
                  f"{paths.video_truth}).", ""]
    return "\n".join(lines)
