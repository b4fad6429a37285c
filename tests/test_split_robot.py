"""The soccer robot split into two processes, the camera image through shared memory
(``python -m humanoid_sim.demo --split``, humanoid_sim.split; issue 20 point 4).

Slow for a test (about 20 s on an idle machine, more under load), and why: it runs the demo
as a user does, in real time (lockstep turns the transport off, see docs/SHM.md), with a
MuJoCo world, its camera and a second container process, each taking seconds to start;
the robot then plays only until perception's detections come back and a plain subscriber
has had a few images.
"""

from __future__ import annotations

import re
import signal
import sys
from pathlib import Path

from sensor_msgs.msg import Image

from efficient_comm.testing import isolated_domain_id

from ._ros import child, peer, wait_until

#: A live line: simulated seconds, RTF, camera fps, detections Hz, ..., and the split's
#: last column, the camera images also written to DDS.
LIVE = re.compile(r"^\s*(\d+\.\d)\s+[\d.]+\s+([\d.]+)\s+([\d.]+)\s.*\s(\d+)\s*$")


def _live(log: Path) -> list[tuple[float, float, float, int]]:
    return [(float(m[1]), float(m[2]), float(m[3]), int(m[4]))
            for line in log.read_text(errors="replace").splitlines()
            if (m := LIVE.match(line))]


def test_split_robot_sends_its_camera_image_through_shared_memory(tmp_path: Path) -> None:
    """Perception (ball detector, JPEG compressor) in a container process of its own: the
    ball is detected there (the body has no detector) from images that crossed through
    shared memory (the image's publisher wrote none to DDS while only perception read
    them), and a plain rclpy subscriber that joins later gets the images over DDS, each
    once."""
    domain = isolated_domain_id()
    log, report = tmp_path / "demo.log", tmp_path / "report.md"
    args: list[str | Path] = [
        sys.executable, "-u", "-m", "humanoid_sim.demo", "--split", "--duration", "0",
        "--stats-period", "0.5", "--report", report, "--bag-dir", tmp_path / "bags"]
    with child(args, domain_id=domain, log=log) as demo:
        # Perception works: detections come back from the other process, none of the
        # images it read having been written to DDS.
        assert wait_until(lambda: any(det > 0 for _, _, det, _ in _live(log)), demo,
                          timeout_s=120), log.read_text()[-3000:]
        seen = [line for line in _live(log) if line[2] > 0]
        assert seen[-1][1] > 0 and seen[-1][3] == 0, seen  # camera running, no DDS copy
        stamps: list[tuple[int, int]] = []

        def on_image(image: Image) -> None:
            stamps.append((image.header.stamp.sec, image.header.stamp.nanosec))

        with peer(domain, "plain_image_reader") as plain:
            plain.node.create_subscription(Image, "/robot/camera/image_raw", on_image, 10)
            assert plain.wait_for(lambda: len(stamps) >= 5, timeout_s=60), \
                log.read_text()[-3000:]
            demo.send_signal(signal.SIGINT)  # Ctrl-C: the demo stops and writes its report
            assert demo.wait(timeout=60) in (0, 3), log.read_text()[-3000:]  # 3: fell
    assert len(set(stamps)) == len(stamps) and stamps == sorted(stamps), stamps  # once each
    text = report.read_text()
    row = re.search(r"\| split: .* \| shm; camera image (\d+) through shared memory, (\d+) "
                    r"also written to DDS; CPU in [\d.]+ s \((\d+) camera frames\): body "
                    r"[\d.]+ s, perception ([\d.]+) s", text)
    assert row is not None, text
    shm, dds, frames, perception_cpu = int(row[1]), int(row[2]), int(row[3]), float(row[4])
    # Every frame rendered once perception was connected went to it through shared memory.
    assert 0 < frames <= shm, (frames, shm)
    # Written to DDS only for the plain subscriber: at least what it got, never all.
    assert len(stamps) <= dds < shm, (len(stamps), dds, shm)
    assert perception_cpu > 0
    detections = re.search(r"\| ball detections \| (\d+)", text)
    assert detections is not None and int(detections[1]) > 0, text
    assert "/robot/ball_detector" not in text, "the body ran a detector of its own"
    # The shared-memory wait's relay left no rclpy handler unrun at exit (Python warned
    # "coroutine ... was never awaited" after every split run).
    assert "never awaited" not in log.read_text(), log.read_text()[-3000:]
