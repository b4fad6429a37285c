"""The offline tools' speed on film and images (issue 21 point 6): the augmented video
exported at least in real time at 640 x 480, and the A/B replay of two ball detectors at
least 10x real time.

Both are measured against the floor any such tool stands on, measured in the same run on
the same input:

* **augment**: ``log_analysis.augment_video`` over a ``--seconds`` film of a rolling ball at
  640 x 480 and ``--fps`` (``log_analysis.testing.film_ball`` with the overhead camera's
  calibration scaled to that size; ``--robots`` robots' beliefs at 10 Hz, an event every
  2 s for captions and the timeline), against **decode + encode**: the same frames decoded
  (as ``ExternalVideo.frames`` gives them) and encoded with the same encoder settings,
  nothing drawn. Figures: seconds of work per second of video (real time is 1.0 or less),
  and against the floor.
* **compare**: ``log_analysis.compare_components`` of ``humanoid_sim::BallDetector`` and
  ``humanoid_sim::BlobBallDetector`` over ``--images`` JPEG images of one robot's camera at
  ``--camera-hz`` (``log_analysis.testing.seen_ball``, 320 x 240 as the robots' cameras,
  with the ground truth), against **read + decode**: the same log read and every image
  decoded, no detector run. Figures: log seconds per second of work (the target is 10x
  or more), and against the floor.

Run: ``source scripts/env.sh && python bench/log_analysis_bench.py`` (``--quick`` for a
smoke run). Prints the medians of ``--repeat`` runs with the load average, and writes every
run to ``--out`` (JSON).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np

from log_analysis import Event, TeamLog
from log_analysis.augment import augment_video
from log_analysis.compare import Variant, compare_components
from log_analysis.sync import VideoFit
from log_analysis.testing import OVERHEAD, film_ball, seen_ball
from log_analysis.video import Calibration, ExternalVideo

NS = 1_000_000_000
WIDTH, HEIGHT = 640, 480


def camera_640x480() -> Calibration:
    """The overhead camera of the test double at 640 x 480: the same pose and horizontal
    field of view (the taller frame sees more of the field's depth)."""
    scale = WIDTH / OVERHEAD.width
    return Calibration(width=WIDTH, height=HEIGHT, fx=OVERHEAD.fx * scale,
                       fy=OVERHEAD.fy * scale, cx=WIDTH / 2, cy=HEIGHT / 2,
                       position=OVERHEAD.position, forward=OVERHEAD.forward, up=OVERHEAD.up)


def _rolling(t: float) -> tuple[float, float]:
    """The ball rolls to and fro along the field (a new pixel position every frame)."""
    return 3.0 * math.sin(t * 0.6), 1.0 * math.cos(t * 0.4)


def _walker(i: int) -> Callable[[float], tuple[float, float, float]]:
    def where(t: float) -> tuple[float, float, float]:
        a = t * 0.3 + i * math.tau / 6
        return 2.5 * math.cos(a), 1.8 * math.sin(a), a + math.pi / 2

    return where


def film(folder: Path, *, seconds: float, fps: int, robots: int) -> tuple[Path, Path]:
    names = ([f"blue{k}" for k in (1, 2, 3)] + [f"red{k}" for k in (1, 2, 3)])[:robots]
    return film_ball(folder, _rolling, seconds=seconds, offset_s=0.0, drift_ppm=0.0, fps=fps,
                     camera=camera_640x480(),
                     robots={name: _walker(i) for i, name in enumerate(names)})


def decode_encode(video: ExternalVideo, output: Path) -> int:
    """The floor of an export: every frame decoded to RGB and encoded again with the
    augmented video's encoder settings, nothing drawn. Returns the frame count."""
    fps = round(float(video.sidecar.get("fps") or 5))
    frames = 0
    with av.open(str(output), "w") as out:
        stream: Any = out.add_stream("libx264", rate=fps)
        cal = video.need_calibration("the floor's frame size")
        stream.width, stream.height = cal.width, cal.height
        stream.pix_fmt = "yuv420p"
        stream.options = {"preset": "veryfast", "crf": "23"}
        for _, rgb in video.frames():
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
            frame.pts = frames
            out.mux(stream.encode(frame))
            frames += 1
        out.mux(stream.encode())
    return frames


def read_decode(log: TeamLog, robot: str) -> int:
    """The floor of a replay: the robot's images read from the log and decoded."""
    count = 0
    for m in log.messages([f"/{robot}/camera/image_raw/compressed"]):
        pixels = cv2.imdecode(np.frombuffer(bytes(m.message.data), np.uint8), cv2.IMREAD_COLOR)
        count += pixels is not None
    return count


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    t0 = time.perf_counter()
    result = fn()
    return time.perf_counter() - t0, result


def run_once(folder: Path, log: Path, video: Path, images: Path, run: int) -> dict[str, Any]:
    source = ExternalVideo(video)
    team = TeamLog(log)
    first, last = team.time_range()
    events = [Event("kick", t, t + NS, "blue1", f"blue1 kicks at {(t - first) / NS:.0f} s")
              for t in range(first, last, 2 * NS)]
    fit = VideoFit(0, 0.0, source.start_ns, 0, "anchors", source.frame_period_ns)
    floor_s, floor_frames = _timed(lambda: decode_encode(source, folder / f"plain{run}.mp4"))
    aug_s, report = _timed(lambda: augment_video(team, source, fit, folder / f"aug{run}.mp4",
                                                 events=events))
    video_s = floor_frames / float(source.sidecar["fps"])
    shots = TeamLog(images)
    i_first, i_last = shots.time_range()
    read_s, decoded = _timed(lambda: read_decode(shots, "blue1"))
    ab_s, comparison = _timed(lambda: compare_components(
        shots, Variant("colour", "humanoid_sim::BallDetector"),
        Variant("blob", "humanoid_sim::BlobBallDetector"), robot="blue1"))
    summary = comparison.summary()
    return {"run": run, "video_s": video_s, "video_frames": floor_frames,
            "augmented_frames": report.frames, "augmented_robots": report.robots,
            "decode_encode_s": floor_s, "augment_s": aug_s,
            "log_s": (i_last - i_first) / NS, "images": len(comparison.frames),
            "decoded_images": decoded, "read_decode_s": read_s, "compare_s": ab_s,
            "hit_rate": {label: summary[label]["hit_rate"] for label in ("colour", "blob")}}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="the film's length")
    parser.add_argument("--fps", type=int, default=25, help="the film's frame rate")
    parser.add_argument("--robots", type=int, default=6, choices=range(0, 7))
    parser.add_argument("--images", type=int, default=300, help="camera images to compare on")
    parser.add_argument("--camera-hz", type=float, default=30.0,
                        help="their rate (the robots' camera_hz)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_name("out") / "log_analysis_bench.json")
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.robots, args.images, args.repeat = 2.0, 2, 30, 1
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        log, video = film(folder, seconds=args.seconds, fps=args.fps, robots=args.robots)
        period = 1 / args.camera_hz
        images = seen_ball(folder / "images", robot="blue1", frames=[
            (1 + k * period, -30.0 + 60.0 * k / max(args.images - 1, 1), k % 7 == 3)
            for k in range(args.images)])
        print(f"filmed {args.seconds:g} s at {WIDTH}x{HEIGHT}, {args.fps} fps, "
              f"{args.robots} robots; {args.images} images at {args.camera_hz:g} Hz in "
              f"{time.perf_counter() - started:.1f} s", file=sys.stderr)
        results = [run_once(folder, log, video, images, run) for run in range(args.repeat)]
    meta = {"date": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "python": platform.python_version(),
            "platform": platform.platform(), "cpu_count": os.cpu_count(),
            "load": os.getloadavg()[0], "seconds": args.seconds, "fps": args.fps,
            "robots": args.robots, "images": args.images, "camera_hz": args.camera_hz,
            "quick": args.quick, "elapsed_s": round(time.perf_counter() - started, 1)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "results": results}, indent=1))
    report(results, meta)
    return 0


def report(results: list[dict[str, Any]], meta: dict[str, Any]) -> None:
    med = statistics.median
    video_s, log_s = results[0]["video_s"], results[0]["log_s"]
    floor, aug = med(r["decode_encode_s"] for r in results), med(r["augment_s"] for r in results)
    read, ab = med(r["read_decode_s"] for r in results), med(r["compare_s"] for r in results)
    print(f"\noffline tools, median of {len(results)} runs, load {meta['load']:.1f} "
          f"({meta['cpu_count']} cores)")
    print(f"augmented video: {results[0]['video_frames']} frames of {WIDTH}x{HEIGHT} at "
          f"{meta['fps']} fps ({video_s:g} s), {meta['robots']} robots")
    print(f"{'':16}{'seconds':>9}{'of video':>10}{'vs floor':>10}")
    for label, s in (("decode+encode", floor), ("augment", aug)):
        print(f"{label:16}{s:9.2f}{s / video_s:10.2f}{s / floor:9.2f}x")
    print(f"target: augment <= 1.0 of the video's duration (real time): "
          f"{aug / video_s:.2f} ({'met' if aug <= video_s else 'NOT met'})")
    print(f"A/B replay: {results[0]['images']} images of 320x240 at {meta['camera_hz']:g} Hz "
          f"({log_s:.1f} s of log), colour vs blob detector")
    print(f"{'':16}{'seconds':>9}{'x real':>10}{'vs floor':>10}")
    for label, s in (("read+decode", read), ("compare", ab)):
        print(f"{label:16}{s:9.2f}{log_s / s:10.1f}{s / read:9.2f}x")
    print(f"target: compare >= 10x real time: {log_s / ab:.1f}x "
          f"({'met' if log_s / ab >= 10 else 'NOT met'})")


if __name__ == "__main__":
    sys.exit(main())
