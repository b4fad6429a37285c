"""What the match's external video costs: CPU per frame, rendering against encoding.

The one-robot world (the simulator, no robot camera, the ball rolling) runs in lockstep for
``--seconds`` of simulated time, twice per repeat:

* ``baseline``: physics alone; its CPU per video period (1/fps of simulated time) is what
  the video's cost is held against;
* ``video``: the same with :class:`humanoid_sim.match_video.MatchVideo` offered at every
  physics step (so the bench also shows that frames are rendered only when due: rendered
  frames = seconds x fps + 1). Encoding (PyAV, H.264, one thread) is the writer thread's
  CPU time; rendering is the rest of what the process spent above the baseline (Mesa's
  llvmpipe rasterises in threads of its own, so the world thread's CPU time would miss
  most of it; ``LP_NUM_THREADS=0`` renders in the caller and gives the same total).

* ``video_msaa4``: the same with MuJoCo's default 4x multisampling, which the video
  leaves off (``samples=0``).

Printed: ms of CPU per frame for rendering and for encoding, and their sum as a ratio of the
physics' CPU per frame period; medians of ``--repeat`` runs.

Run: ``source scripts/env.sh && python bench/match_video_bench.py`` (``--quick`` for a smoke
run).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "bench" / "out" / "match_video_bench.json"


def _world() -> tuple[Any, Any]:
    from efficient_comm.testing import TestHandle, test_container
    from humanoid_sim.simulator import Simulator

    container = test_container()
    sim = Simulator(TestHandle("sim", container=container, parameters={
        "camera_hz": 0.0, "ball_velocity": [1.0, 0.5], "robot_pose": [-3.0, 2.0, 0.0]}))
    return container, sim


def run(seconds: float, *, fps: float, width: int, height: int, video: bool, samples: int,
        directory: Path) -> dict[str, float]:
    from humanoid_sim.match_video import MatchVideo

    container, sim = _world()
    match = None
    try:
        if video:
            match = MatchVideo(sim.model, sim.data, directory / f"m{time.monotonic_ns()}.mp4",
                               offset_ns=0, fps=fps, width=width, height=height,
                               lock=sim.pty.lock, samples=samples)
        clock = container.executor.clock
        steps = round(seconds / sim.period_s)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        for _ in range(steps):
            if match is not None:
                match.offer(clock.now_ns())
            container.advance(sim.period_s)
        if match is not None:
            match.offer(clock.now_ns())  # the end of the run: the last frame due
            match.close()  # the encoder's last frames belong to the run
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    finally:
        if match is not None:
            match.close()
        sim.close()
    out = {"cpu_s": cpu, "wall_s": wall, "steps": steps}
    if match is not None:
        out |= {"frames": match.frames, "render_wall_ms": match.render_ns / match.frames / 1e6,
                "encode_ms": match.encode_ns / match.frames / 1e6}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=8.0, help="simulated seconds per run")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--fps", type=float, default=12.5)
    parser.add_argument("--size", default="640x360", help="WIDTHxHEIGHT")
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.repeat = 1.0, 1
    width, height = (int(v) for v in args.size.split("x"))
    runs: dict[str, list[dict[str, float]]] = {"baseline": [], "video": [], "video_msaa4": []}
    with tempfile.TemporaryDirectory() as directory:
        for _ in range(args.repeat):
            for kind in runs:
                runs[kind].append(run(args.seconds, fps=args.fps, width=width, height=height,
                                      video=kind != "baseline",
                                      samples=4 if kind == "video_msaa4" else 0,
                                      directory=Path(directory)))

    def median(kind: str, key: str) -> float:
        return statistics.median(r[key] for r in runs[kind])

    frames_per_run = int(args.seconds * args.fps) + 1
    physics_ms = median("baseline", "cpu_s") * 1e3 / (args.seconds * args.fps)
    encode_ms = median("video", "encode_ms")
    video_ms = (median("video", "cpu_s") - median("baseline", "cpu_s")) * 1e3 / frames_per_run
    render_ms = video_ms - encode_ms
    msaa4_ms = (median("video_msaa4", "cpu_s") - median("baseline", "cpu_s")) * 1e3 \
        / frames_per_run
    summary = {
        "fps": args.fps, "width": width, "height": height, "seconds": args.seconds,
        "frames": median("video", "frames"), "frames_expected": frames_per_run,
        "physics_ms_per_period": physics_ms, "render_ms": render_ms, "encode_ms": encode_ms,
        "render_wall_ms": median("video", "render_wall_ms"), "video_ms": video_ms,
        "ratio_to_physics": video_ms / physics_ms,
        "msaa4_video_ms": msaa4_ms, "msaa4_ratio": msaa4_ms / video_ms,
    }
    print(f"match video {width}x{height} at {args.fps:g} fps, {args.seconds:g} simulated s, "
          f"median of {args.repeat}:")
    print(f"  frames rendered            {summary['frames']:.0f} (due: {frames_per_run})")
    print(f"  baseline: physics per 1/fps {physics_ms:7.2f} ms CPU")
    print(f"  video per frame             {video_ms:7.2f} ms CPU (process, above the baseline)")
    print(f"    encode                    {encode_ms:7.2f} ms CPU (writer thread)")
    print(f"    render                    {render_ms:7.2f} ms CPU (the rest; "
          f"{summary['render_wall_ms']:.2f} ms wall on the world's thread)")
    print(f"  video / physics per frame   {summary['ratio_to_physics']:7.2f}x")
    print(f"  with 4x multisampling       {msaa4_ms:7.2f} ms CPU per frame, "
          f"{summary['msaa4_ratio']:.2f}x the video's")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "runs": runs}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
