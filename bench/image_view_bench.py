"""Frames per second the image view actually draws in a browser, for a 30 fps camera.

A robot process (``--source synthetic``: bench/_image_camera.py, a 30 fps 320x240 camera
with the real ball detector and JPEG compressor; ``--source sim``: the simulated soccer
robot, whose camera runs below 30 fps when the machine is loaded), ``debug_gui`` started as
a user starts it with one image view, and headless chromium showing it. Per run, over
``--seconds``: the frames the page drew (its own counter, read through JavaScript) and, as
the baseline measured in the same window, the frames the camera produced (one debug drawing
per camera frame, counted by a plain subscriber here). Printed: both rates and their ratio
per run, then the medians over ``--repeat`` runs.

Run: ``source scripts/env.sh && python bench/image_view_bench.py`` (``--quick``: one short
run, for the smoke test).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import statistics
import sys
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from efficient_comm.testing import isolated_domain_id  # noqa: E402
from tests._gui import gui, new_browser, robot, started, wait_for  # noqa: E402
from tests.test_gui_image_browser import image_layout, image_state  # noqa: E402

NAMESPACE = "/robot"


def _camera(stack: ExitStack, tmp: Path, domain: int, source: str) -> Any:
    if source == "sim":
        return stack.enter_context(robot(tmp, domain_id=domain, namespace=NAMESPACE))
    from efficient_comm.testing import ros_env
    from tests._gui import RobotProcess

    log = tmp / "camera.log"
    proc = stack.enter_context(started(
        [sys.executable, ROOT / "bench" / "_image_camera.py", "--namespace", NAMESPACE],
        env=ros_env(domain), log=log))
    return RobotProcess(proc=proc, log=log, domain_id=domain, namespace=NAMESPACE)


class _FrameCounter:
    """Counts the camera's frames: one debug drawing is published per frame."""

    def __init__(self, domain: int) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        from efficient_comm_interfaces.msg import ImageMarkerArray

        self.count = 0
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("image_bench_counter", context=self.context)
        self.node.create_subscription(ImageMarkerArray, f"{NAMESPACE}/ball/debug_markers",
                                      self._on, 50)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        import threading

        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on(self, _msg: Any) -> None:
        self.count += 1

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        with contextlib.suppress(ExternalShutdownException):
            while self.context.ok():
                self.executor.spin_once(timeout_sec=0.1)

    def close(self) -> None:
        import rclpy

        rclpy.shutdown(context=self.context)
        self.thread.join(timeout=5)


def measure(tmp: Path, *, source: str, seconds: float, warmup_s: float) -> dict[str, float]:
    domain = isolated_domain_id()
    with ExitStack() as stack:
        cam = _camera(stack, tmp, domain, source)
        server = stack.enter_context(gui(tmp, domains=[domain], args=[
            "--layout", str(image_layout(tmp / "layout.json"))]))
        counter = _FrameCounter(domain)
        stack.callback(counter.close)
        browser = new_browser()
        stack.callback(browser.quit)
        browser.get(server.url)
        wait_for(lambda: (s := image_state(browser)) and s[0] >= 5, what="frames",
                 alive=[cam, server], timeout_s=90)
        time.sleep(warmup_s)  # a measurement window, not synchronisation
        shown0, cam0, t0 = image_state(browser)[0], counter.count, time.monotonic()  # type: ignore[index]
        time.sleep(seconds)
        shown1, cam1, t1 = image_state(browser)[0], counter.count, time.monotonic()  # type: ignore[index]
        status = browser.find_element("css selector", '[data-testid^="image-status-"]').text
    wall = t1 - t0
    shown_fps, camera_fps = (shown1 - shown0) / wall, (cam1 - cam0) / wall
    received = re.search(r"([\d.]+) fps received", status)
    return {"shown_fps": shown_fps, "camera_fps": camera_fps,
            # What the GUI server received (its status line): tells a slow link or server
            # from a slow browser.
            "received_fps": float(received.group(1)) if received else 0.0,
            "ratio": shown_fps / camera_fps if camera_fps else 0.0, "window_s": wall}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--source", choices=("synthetic", "sim"), default="synthetic")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--quick", action="store_true", help="one run of 2 s (smoke test)")
    ap.add_argument("--out", type=Path, default=None, help="write the records as JSON")
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.seconds = 1, 2.0
    import tempfile

    records = []
    for run in range(args.repeat):
        with tempfile.TemporaryDirectory(prefix="image_bench_") as tmp:
            rec = measure(Path(tmp), source=args.source, seconds=args.seconds,
                          warmup_s=0.5 if args.quick else 2.0)
        records.append(rec)
        print(f"run {run + 1}: camera {rec['camera_fps']:.1f} fps, browser drew "
              f"{rec['shown_fps']:.1f} fps (ratio {rec['ratio']:.2f}; the GUI server received "
              f"{rec['received_fps']:.1f} fps)", flush=True)
    med = {k: statistics.median(r[k] for r in records)
           for k in ("camera_fps", "shown_fps", "ratio", "received_fps")}
    print(f"median of {len(records)} ({args.source} camera, 320x240): camera "
          f"{med['camera_fps']:.1f} fps, browser {med['shown_fps']:.1f} fps, "
          f"ratio {med['ratio']:.2f} (target: >= 15 fps drawn for a 30 fps camera)")
    if args.out is not None:
        args.out.write_text(json.dumps({"source": args.source, "records": records,
                                        "median": med}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
