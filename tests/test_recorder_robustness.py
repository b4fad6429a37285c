"""What a recording survives: SIGKILL, a full disk, the free-space guard; splitting, snapshots.

The recorder runs composed with other components; when its disk fails they keep running.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import pytest
from mcap.reader import SeekingReader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from rosbags.rosbag2 import Reader as Rosbag2Reader
from sensor_msgs.msg import Image
from std_msgs.msg import String

from efficient_comm.handle import NodeHandle
from efficient_comm.testing import TestHandle, test_container, unique_topic
from robot_recorder import FileSystem, PlaybackError, Recorder, RecorderConfigError
from robot_recorder.bag import read_messages, recover
from robot_recorder.testing import drained, read_rosbags
from robot_recorder.writer import FAILED, IDLE

CHILD = Path(__file__).with_name("_recorder_child.py")


class Camera:
    """64 KiB images, numbered in the first bytes, one per call."""

    def __init__(self, node: NodeHandle, topic: str) -> None:
        self.pub = node.create_publisher(Image, topic, qos=100)
        self.i = 0

    def shoot(self) -> None:
        data = self.i.to_bytes(4, "little") + os.urandom(64 * 1024 - 4)  # incompressible
        self.pub.publish(Image(height=256, width=256, encoding="mono8", step=256, data=data))
        self.i += 1


class Controller:
    """Stands for the robot's other components: must keep running whatever the disk does."""

    def __init__(self, node: NodeHandle) -> None:
        self.ticks = 0
        node.create_timer(0.01, self._tick)

    def _tick(self) -> None:
        self.ticks += 1


def _numbers(bag: Path) -> list[int]:
    return [int.from_bytes(m.data[-(64 * 1024):][:4], "little") if m.type.endswith("Image")
            else int(m.data[8:-1].decode()) for m in read_messages(bag)]


def _readable(bag: Path) -> int:
    try:
        return len(list(read_messages(bag)))
    except PlaybackError:  # the first file is opened with the first message
        return 0


def test_sigkill_leaves_a_file_readable_up_to_its_last_chunk(tmp_path: Path) -> None:
    topic = unique_topic("count")
    bag = tmp_path / "killed"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen([sys.executable, str(CHILD), str(bag), topic], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.strip() == b"recording", line + proc.stdout.read(4096)
        # 200 small messages a second never fill a 1 MiB chunk: only the time-based chunk
        # flush (at least every second) makes them readable while the recorder runs.
        deadline = time.monotonic() + 20
        while _readable(bag) < 400:
            assert time.monotonic() < deadline, "no chunk became readable"
            time.sleep(0.05)  # polling a file another process writes: no event to wait on
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()
    (mcap,) = bag.glob("*.mcap")
    # Independent of our reader: the mcap library's stream reader reads the file to its end
    # (it is a valid MCAP file at every moment: rosbag2_layout.livefile).
    with open(mcap, "rb") as f:
        seen = [int(record.data[8:-1].decode()) for record in StreamReader(f).records
                if isinstance(record, Message)]
    assert len(seen) >= 400 and seen == list(range(len(seen)))
    problems: list[str] = []
    assert [int(m.data[8:-1].decode()) for m in read_messages(bag, problems=problems)] == seen
    assert problems == []
    # metadata.yaml lists the file as of its last flush, so rosbags and rosbag2 open the bag
    # with every message.
    with Rosbag2Reader(bag) as reader:
        assert reader.message_count >= 400
    assert [int(m.data) for _, m in read_rosbags(bag)] == seen
    # recover() writes a complete bag that rosbags reads.
    assert recover(bag, tmp_path / "recovered") == len(seen)
    assert [int(m.data) for _, m in read_rosbags(tmp_path / "recovered")] == seen


class _FullAfter(FileSystem):
    """A file system that fills up after ``limit`` bytes (ENOSPC), as a full disk does."""

    def __init__(self, limit: int) -> None:
        self.left = limit

    def open_new(self, path: Path) -> IO[bytes]:
        return _Stream(super().open_new(path), self)  # type: ignore[return-value]

    def write_text(self, path: Path, text: str) -> None:
        if len(text) > self.left:  # metadata.yaml too: a full disk refuses every write
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        super().write_text(path, text)


class _Stream:
    def __init__(self, inner: IO[bytes], fs: _FullAfter) -> None:
        self.inner, self.fs = inner, fs

    def write(self, data: Any) -> int:
        if len(data) > self.fs.left:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.fs.left -= len(data)
        return self.inner.write(data)

    def tell(self) -> int:
        return self.inner.tell()

    def seek(self, offset: int) -> int:
        return self.inner.seek(offset)

    def truncate(self, size: int) -> int:
        return self.inner.truncate(size)

    def flush(self) -> None:
        self.inner.flush()

    def close(self) -> None:
        self.inner.close()


def _robot(tmp_path: Path, *, min_free_bytes: int = 0, **options: Any
           ) -> tuple[Any, Camera, Controller, Recorder, Any]:
    topic = unique_topic("camera")
    container = test_container()
    camera = Camera(TestHandle("camera", container=container), topic)
    controller = Controller(TestHandle("controller", container=container))
    handle = TestHandle("recorder", container=container,
                        parameters={"chunk_bytes": 200_000, "min_free_bytes": min_free_bytes})
    recorder = Recorder(handle, topics=[topic], output_dir=tmp_path, **options)
    return container, camera, controller, recorder, handle


def test_full_disk_stops_recording_cleanly_and_the_robot_keeps_running(tmp_path: Path) -> None:
    fs = _FullAfter(1_000_000)
    container, camera, controller, recorder, handle = _robot(tmp_path, fs=fs)
    bag = recorder.start(tmp_path / "bag").result(10)
    for _ in range(40):  # 2.6 MB of images onto a 1 MB disk
        camera.shoot()
        container.advance(0.05)
        drained(recorder.writer)
    assert controller.ticks == 200  # every 10 ms for 2 s: untouched by the failure
    status = recorder.status()
    assert status.state == FAILED and "No space left" in status.error, status.error
    assert handle.published("~/status")[-1].state == FAILED
    numbers = _numbers(bag)
    assert numbers and numbers == list(range(len(numbers)))  # complete chunks stay readable
    assert len(numbers) < 40
    with Rosbag2Reader(bag) as reader:  # metadata.yaml as of the last flush before it filled
        assert 0 < reader.message_count <= len(numbers)
    assert recover(bag, tmp_path / "recovered") == len(numbers)
    # A new recording starts again once there is space.
    fs.left = 1 << 30
    recorder.start(tmp_path / "again").result(10)
    camera.shoot()
    recorder.close()
    assert _numbers(tmp_path / "again") == [40]


class _Shrinking(FileSystem):
    def __init__(self, free: int) -> None:
        self.free = free

    def free_bytes(self, path: Path) -> int:
        return self.free


def test_free_space_guard_closes_the_bag_before_the_disk_is_full(tmp_path: Path) -> None:
    fs = _Shrinking(10 << 30)
    container, camera, _, recorder, _ = _robot(tmp_path, fs=fs, min_free_bytes=1 << 30)
    bag = recorder.start(tmp_path / "bag").result(10)
    for i in range(10):
        if i == 5:
            fs.free = 512 << 20  # someone else filled the disk
        camera.shoot()  # a 200 kB chunk every third image: the guard asks at each
        container.advance(0.1)
        drained(recorder.writer)
    status = recorder.status()
    assert status.state == FAILED and "free-space guard" in status.error
    recorder.close()
    (mcap,) = bag.glob("*.mcap")
    with open(mcap, "rb") as f:  # closed properly: summary and footer present
        summary = SeekingReader(f).get_summary()
        assert summary is not None and summary.statistics is not None
    assert 5 <= len(read_rosbags(bag)) <= 8


def _can_mount_tmpfs() -> bool:
    return os.geteuid() == 0 and sys.platform == "linux"


@contextmanager
def _tmpfs(where: Path, size: str) -> Iterator[Path]:
    where.mkdir()
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                            capture_output=True, text=True)
    if result.returncode:
        pytest.skip(f"cannot mount a tmpfs: {result.stderr.strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


@pytest.mark.skipif(not _can_mount_tmpfs(), reason="needs root to mount a small tmpfs")
@pytest.mark.parametrize("guard", [0, 600_000], ids=["disk-full", "guard"])
def test_real_small_file_system(tmp_path: Path, guard: int) -> None:
    with _tmpfs(tmp_path / f"disk_{uuid.uuid4().hex[:6]}", "2m") as disk:
        container, camera, controller, recorder, _ = _robot(disk, min_free_bytes=guard)
        bag = recorder.start(disk / "bag").result(10)
        for _ in range(60):
            camera.shoot()
            container.advance(0.05)
            drained(recorder.writer)
        assert controller.ticks == 300
        status = recorder.status()
        recorder.close()
        assert status.state == FAILED
        assert ("free-space guard" if guard else "No space left") in status.error
        numbers = _numbers(bag)
        assert numbers and numbers == list(range(len(numbers)))
        if guard:  # stopped in time: the bag is complete, rosbags reads it
            assert len(read_rosbags(bag)) == len(numbers)


def _texts(container: Any, pub: Any, n: int, dt: float) -> list[str]:
    sent = []
    for i in range(n):
        text = f"message {i:04d} " + "x" * 80
        pub.publish(String(data=text))
        sent.append(text)
        container.advance(dt)
    return sent


def _string_robot(tmp_path: Path, **parameters: Any) -> tuple[Any, Any, Recorder]:
    topic = unique_topic("text")
    container = test_container()
    pub = TestHandle("talker", container=container).create_publisher(String, topic, qos=100)
    recorder = Recorder(TestHandle("recorder", container=container, parameters=parameters),
                        topics=[topic], output_dir=tmp_path)
    return container, pub, recorder


@pytest.mark.parametrize(("parameters", "files"), [
    ({"max_file_bytes": 2000}, 5),  # ~100 bytes a message: 20 per file
    ({"max_file_duration_s": 0.25}, 4),  # 10 ms apart: 25 per file
])
def test_split_by_size_and_duration(tmp_path: Path, parameters: dict[str, Any],
                                    files: int) -> None:
    container, pub, recorder = _string_robot(tmp_path, **parameters)
    bag = recorder.start(tmp_path / "bag").result(10)
    sent = _texts(container, pub, 100, 0.01)
    recorder.close()
    assert len(list(bag.glob("*.mcap"))) == files
    assert [m.data for _, m in read_rosbags(bag)] == sent  # across files, in order


def test_split_on_command_and_stop_start(tmp_path: Path) -> None:
    container, pub, recorder = _string_robot(tmp_path)
    bag = recorder.start(tmp_path / "bag").result(10)
    sent = _texts(container, pub, 10, 0.01)
    first = recorder.split().result(10)
    sent += _texts(container, pub, 10, 0.01)
    recorder.split().result(10)
    sent += _texts(container, pub, 10, 0.01)
    assert recorder.stop().result(10) == bag
    assert recorder.status().state == IDLE
    _texts(container, pub, 5, 0.01)  # not recording: not written
    recorder.close()
    assert first == bag / "bag_0.mcap"
    assert sorted(p.name for p in bag.glob("*.mcap")) == [f"bag_{i}.mcap" for i in range(3)]
    assert [m.data for _, m in read_rosbags(bag)] == sent


def test_snapshot_writes_the_last_seconds_bounded_in_bytes(tmp_path: Path) -> None:
    container, pub, recorder = _string_robot(tmp_path, snapshot_bytes=4000,
                                             snapshot_seconds=0.5)
    sent = _texts(container, pub, 200, 0.01)  # not recording; the ring buffer keeps the tail
    drained(recorder.writer)
    status = recorder.status()
    assert 0 < status.snapshot_bytes <= 4000 and status.snapshot_seconds <= 0.5
    path, count = recorder.snapshot(tmp_path / "event").result(10)
    got = [m.data for _, m in read_rosbags(path)]
    assert got == sent[-len(got):] and len(got) == count
    assert 30 <= count <= 40  # 4000 bytes of ~100-byte messages bind before 0.5 s (50)
    container2, pub2, recorder2 = _string_robot(tmp_path / "2", snapshot_bytes=1 << 20,
                                                snapshot_seconds=0.5)
    sent2 = _texts(container2, pub2, 200, 0.01)
    path2, count2 = recorder2.snapshot(tmp_path / "event2").result(10)
    assert [m.data for _, m in read_rosbags(path2)] == sent2[-count2:] and count2 == 51
    recorder.close()
    recorder2.close()


def test_snapshot_when_off_is_an_error(tmp_path: Path) -> None:
    _, _, recorder = _string_robot(tmp_path)
    with pytest.raises(RecorderConfigError):
        recorder.snapshot(tmp_path / "x").result(10)
    recorder.close()


class _Broken(_FullAfter):
    """Writes fail with an error no one foresaw (not an OSError) while ``broken``."""

    def __init__(self) -> None:
        super().__init__(1 << 30)
        self.broken = True

    def open_new(self, path: Path) -> IO[bytes]:
        return _Raising(FileSystem.open_new(self, path), self)  # type: ignore[return-value]


class _Raising(_Stream):
    fs: _Broken

    def write(self, data: Any) -> int:
        if self.fs.broken:
            raise ValueError("unforeseen")
        return super().write(data)


def test_an_unforeseen_error_stops_the_recording_and_the_writer_lives_on(
        tmp_path: Path) -> None:
    fs = _Broken()
    container, camera, controller, recorder, handle = _robot(tmp_path, fs=fs)
    recorder.start(tmp_path / "bag").result(10)
    camera.shoot()
    container.advance(0.05)
    drained(recorder.writer)
    status = recorder.status()
    assert status.state == FAILED and "ValueError('unforeseen')" in status.error, status.error
    assert status.drops == 1  # the message that met the error is counted, not lost quietly
    container.advance(0.0)  # the writer thread's status publish is queued to the executor
    assert handle.published("~/status")[-1].state == FAILED
    assert controller.ticks == 5
    # The writer thread survived: the next recording, on a working disk, is written.
    fs.broken = False
    recorder.start(tmp_path / "again").result(10)
    camera.shoot()
    recorder.close()
    assert _numbers(tmp_path / "again") == [1]
