"""The team match's merged log, as a user's match leaves it: every robot's topics in the
world's time within 1 ms (or the bound the merge states).

Two teammates (real time, cameras at 5 Hz, the video at 2 fps), each robot's software in a
process of its own on a clock of its own (offset by a tenth of a second to most of one,
drifting), measured against the world by team_clock's ``ClockSync``. The world stamps each
robot's ground truth with its own time and records it; the robot receives the same message
and records it on board, on its own clock. Merged, every robot copy is one of the world's
messages and none lies before the world sent it; and its merged time is the world time at
which the robot recorded it (its clock's truth, written beside its bag, inverted) within
1 ms, or within the bound the merge states where that is wider (the online estimates'
round trips grow under load), from the robot's first valid clock estimate on. Without the
merge, or with the offsets not applied, the copies lie hundreds of milliseconds off.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from geometry_msgs.msg import PoseStamped
from rclpy.serialization import deserialize_message

from efficient_comm import from_msg
from rosbag2_layout import BagReader
from team_clock import OffsetModel, SkewedClock
from team_clock_interfaces.msg import ClockOffset

from ._match import MatchProcess

MS = 1_000_000
ROBOTS = ("blue1", "blue2")


class _Never:
    """The base of a clock only mapped, never read."""

    def now_ns(self) -> int:
        raise AssertionError("not read")


def test_the_merged_log_holds_every_robots_topics_within_1_ms_of_ground_truth(
        tmp_path: Path) -> None:
    out, report = tmp_path / "out", tmp_path / "report.md"
    with MatchProcess(["--robots", "2", "--duration", "0", "--ready-s", "4",
                       "--camera-hz", "5", "--video-fps", "2", "--stats-period", "1",
                       "--out-dir", str(out), "--report", str(report)],
                      cwd=tmp_path) as match:
        # Both robots play (they received the referee's game); then 15 more live lines of
        # the game, so that each robot's clock sync has exchanges in its bag.
        for robot in ROBOTS:
            match.until(rf"^  {robot} +\w+ +\w+ +game playing", 150)
        for _ in range(15):
            match.until(r"^ *[\d.]+ s wall, +[\d.]+ s simulated", 20)
        match.interrupt()
        match.wait(120)
    text = report.read_text()
    merged_line = re.search(r"^merged log (\S+): (\d+) messages", text, re.MULTILINE)
    assert merged_line, text
    merged = Path(merged_line[1])
    assert merged.is_absolute() or (tmp_path / merged).exists() or merged.exists(), text
    merged = merged if merged.exists() else tmp_path / merged

    world_stamps: dict[str, set[int]] = {r: set() for r in ROBOTS}
    copies: dict[str, list[tuple[int, int]]] = {r: [] for r in ROBOTS}  # (log time, stamp)
    topics: set[str] = set()
    for message in BagReader(merged).messages():
        topics.add(message.topic)
        for robot in ROBOTS:
            if message.topic == f"/world/ground_truth/{robot}/pose":
                pose = deserialize_message(message.data, PoseStamped)
                world_stamps[robot].add(from_msg(pose.header.stamp))
            elif message.topic == f"/{robot}/ground_truth/pose":
                pose = deserialize_message(message.data, PoseStamped)
                copies[robot].append((message.log_time_ns, from_msg(pose.header.stamp)))

    errors: dict[str, list[float]] = {}
    bounds: dict[str, list[float]] = {}
    for robot in ROBOTS:
        # What the offline tools need, from each robot, in the one file.
        for topic in ("camera/image_raw/compressed", "ball/debug_markers",
                      "efficient_comm/stats", "localization/pose", "role", "game_state",
                      "ground_truth/ball", "team_clock/offset"):
            assert f"/{robot}/{topic}" in topics, (robot, topic, sorted(topics))
        # The robot's copies are the world's messages, and none lies before it was sent.
        pairs = [(log, stamp) for log, stamp in copies[robot] if stamp in world_stamps[robot]]
        assert len(pairs) >= 20 and len(pairs) == len(copies[robot]), (
            robot, len(copies[robot]), len(world_stamps[robot]))
        assert min(log - stamp for log, stamp in pairs) > -1 * MS, robot
        # Each copy's merged time against the world time it was recorded at, from the
        # robot's recorded (local) time and its clock's truth; from its first valid
        # estimate on (before it, team_clock extrapolates the first one back).
        bag = next(p for p in (out / "bags").glob(f"*/{robot}/*") if p.is_dir())
        truth = json.loads((bag.parent / "clock_truth.json").read_text())
        clock = SkewedClock(_Never(), offset_ns=truth["offset_ns"],
                            drift_ppm=truth["drift_ppm"], epoch_ns=truth["epoch_ns"])
        first_valid = min(m.log_time_ns for m in BagReader(bag).messages()
                          if m.topic.endswith("team_clock/offset")
                          and deserialize_message(m.data, ClockOffset).valid)
        local = [m.log_time_ns for m in BagReader(bag).messages()
                 if m.topic == f"/{robot}/ground_truth/pose"]
        assert len(local) == len(pairs), robot
        model = OffsetModel.from_mcap(bag)
        errors[robot] = [(merged_ns - clock.base_of(local_ns)) / MS
                         for local_ns, (merged_ns, _) in zip(local, pairs, strict=True)
                         if local_ns >= first_valid]
        # What the merge claims: the model's own bound at each copy (its estimates' round
        # trips; a millisecond or two on a quiet machine, more under load).
        bounds[robot] = [max(1.0, model.uncertainty_at(local_ns) / MS)
                         for local_ns in local if local_ns >= first_valid]
        assert len(errors[robot]) >= 10, (robot, errors[robot])
    worst = {robot: max(abs(e) for e in errs) for robot, errs in errors.items()}
    print(f"worst merged-time error per robot (ms): {worst}")
    for robot, errs in errors.items():
        # Within 1 ms, or within the bound the merge states where that is wider (the 1 ms
        # held at load 1 to 3: 0.6 and 1.0 ms; under load the online estimates' bounds grow).
        outside = [(e, b) for e, b in zip(errs, bounds[robot], strict=True) if abs(e) > b]
        assert not outside, (robot, outside[:5], worst, text)
    for topic in ("/world/game_state", "/world/ground_truth/ball", "/diagnostics"):
        assert any(t.endswith(topic) for t in topics), (topic, sorted(topics))

    # The video beside it, on a camera clock of its own that its truth file gives.
    video = re.search(r"^External video (\S+) written, on a camera clock ([-+\d.]+) s",
                      text, re.MULTILINE)
    assert video, text
    path = Path(video[1]) if Path(video[1]).exists() else tmp_path / video[1]
    sidecar = json.loads(Path(f"{path}.json").read_text())
    assert sidecar["frames"] > 0 and sidecar["calibration"]["fx"] > 0
    truth = json.loads(path.with_suffix("").with_suffix(".truth.json").read_text())
    assert abs(truth["offset_ns"] / 1e9 - float(video[2])) < 1e-3
