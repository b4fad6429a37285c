"""The soccer robot as two processes on one machine: the body and perception.

``python -m humanoid_sim.demo --split`` runs the robot so: this module owns where the line
between the two runs, and starts the perception process as a user would, ``ros2 run
efficient_comm container --config <file>`` with the container file written here.

**Where the line runs follows the data.** The simulator serves the servo bus (a pty, a
request and its reply 100 times a second, synced with the emulator before every physics
step) and renders the head camera from the very MuJoCo state it steps, so it stays with the
servo driver. So does everything that reads the servos or the IMU at 100 Hz: the ball model,
the head behaviour, the striker, the walk, the kick, the get-up, the motion arbiter, the fall
detector, and the monitor and referee, which score against the simulator's ground truth.
What moves is what reads the camera image and nothing else: the ball detector and the JPEG
compressor. Then the one large message of the robot, the 320x240 rgb8 image (230 kB, 30 Hz),
is what crosses, through shared memory (:mod:`efficient_comm.shm`) with ``transport="shm"``,
over DDS with ``transport="dds"`` (the baseline a benchmark compares with); what comes back
(``ball/detection``, ``ball/debug_markers``: tens of bytes) goes over DDS.

The other way round (simulator and camera with perception, the driver and the motions
apart) would send no image across at all, but the servo bus and every 100 Hz joint state
would cross instead, and in lockstep the driver needs the emulator's own port handler
(:mod:`.dynamixel.pty`), which only a driver in the simulator's process can have.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
from collections import deque
from pathlib import Path
from typing import Any

import yaml

from efficient_comm import Container, exit_with_parent

from .arguments import TRANSPORTS, Transport
from .errors import ProcessError

#: The perception process's components: (registered class, node name).
PERCEPTION = (
    ("humanoid_sim::BallDetector", "ball_detector"),
    ("debug_probes::JpegCompressor", "jpeg_compressor"),
)
#: The container's node name (its statistics are the robot's, beside the body's).
PERCEPTION_NAME = "perception"
#: The container command's line for each component it loaded.
_LOADED = re.compile(r"\]: loaded \S+ as /")


def perception_document(namespace: str) -> dict[str, Any]:
    """The perception process's container file (as a document) for the robot ``namespace``."""
    return {"components": [{"class": cls, "name": name, "namespace": namespace}
                           for cls, name in PERCEPTION]}


def container_command() -> Path:
    """What ``ros2 run efficient_comm container`` runs."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        prefix = Path(get_package_prefix("efficient_comm"))
    except PackageNotFoundError as exc:
        raise ProcessError("efficient_comm is not installed: build the workspace "
                           "(scripts/setup.sh)") from exc
    return prefix / "lib" / "efficient_comm" / "container"


class Perception:
    """The perception process of a split robot, as a context manager: started (its
    container file written into ``config_dir``) and awaited until both components are
    loaded, stopped with Ctrl-C's signal on exit. Its output goes to this process's stderr,
    its first lines also to :attr:`lines` (quoted if it fails to start).
    """

    def __init__(self, *, namespace: str, transport: Transport, config_dir: Path,
                 ready_timeout_s: float = 60.0) -> None:
        if transport not in TRANSPORTS:
            raise ProcessError(f"transport {transport!r}: one of {', '.join(TRANSPORTS)}")
        self.namespace = namespace
        self.transport = transport
        self.config = config_dir / "perception.yaml"
        self.ready_timeout_s = ready_timeout_s
        self.lines: deque[str] = deque(maxlen=20)
        self._loaded = 0
        self._ready = threading.Event()
        self._proc: subprocess.Popen[str] | None = None
        self._pump: threading.Thread | None = None

    def __enter__(self) -> Perception:
        self.config.write_text(yaml.safe_dump(perception_document(self.namespace)))
        env = {**os.environ, "EFFICIENT_COMM_SHM": "1" if self.transport == "shm" else "0"}
        self._proc = subprocess.Popen(
            [str(container_command()), "--config", str(self.config), "--name", PERCEPTION_NAME,
             "--stats-namespace", self.namespace],
            env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, start_new_session=True,
            preexec_fn=exit_with_parent)  # killed with the demo, however it ends
        self._pump = threading.Thread(target=self._read, name="perception output", daemon=True)
        self._pump.start()
        if not self._ready.wait(self.ready_timeout_s) or self._loaded < len(PERCEPTION):
            self.close()
            said = " | ".join(self.lines) or "nothing"
            raise ProcessError(f"the perception process did not load its components "
                               f"(exit status {self._proc.returncode}); it said: {said}")
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def wait_connected(self, container: Container) -> None:
        """Spin ``container`` (the body's) until it has discovered perception's camera
        subscription and ball detection publisher, at most :attr:`ready_timeout_s`;
        ProcessError if it did not or the process ended.

        "Loaded" only says the components exist: discovery takes up to a few seconds more
        on a loaded machine, in which the camera's images would reach nobody and a short
        run would see no ball (13 detections of 55 frames in a 2 s run, and none in one).
        """
        ns = self.namespace.rstrip("/")
        detector = f"{ns}/ball_detector"

        def connected() -> bool:
            return (detector in container.subscriber_nodes(f"{ns}/camera/image_raw")
                    and detector in container.publisher_nodes(f"{ns}/ball/detection")
                    ) or not self.alive()

        if not container.spin_until(connected, timeout_s=self.ready_timeout_s) or not self.alive():
            raise ProcessError(f"the perception process (pid {self.pid}) was not discovered "
                               f"within {self.ready_timeout_s:g} s"
                               f"{'' if self.alive() else ' (it ended)'}")

    def _read(self) -> None:
        """Pass the process's output through; readiness is its container's "loaded" lines
        (set too when it ends, so that a failed start is not waited for in vain)."""
        assert self._proc is not None and self._proc.stdout is not None
        for line in self._proc.stdout:
            self.lines.append(line.rstrip())
            print(f"perception: {line}", end="", file=sys.stderr, flush=True)
            if _LOADED.search(line):
                self._loaded += 1
                if self._loaded == len(PERCEPTION):
                    self._ready.set()
        self._proc.wait()
        self._ready.set()

    @property
    def pid(self) -> int:
        if self._proc is None:
            raise ProcessError("the perception process is not running")
        return self._proc.pid

    def cpu_s(self) -> float:
        """CPU seconds the process used so far (user and system, all its threads)."""
        try:
            fields = Path(f"/proc/{self.pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError as exc:
            raise ProcessError(f"the perception process is gone ({exc.strerror})") from exc
        # utime and stime are fields 14 and 15 of stat(5), counted from the state (field 3)
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def alive(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    def close(self) -> None:
        """Stop the process as Ctrl-C does (its container unloads its components), killing
        its group if it has not ended within 10 s."""
        proc = self._proc
        if proc is None:
            return
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        if self._pump is not None:
            self._pump.join(timeout=5)
        if proc.stdout is not None:
            proc.stdout.close()
