"""What several robots in one world cost: CPU per physics step, split into physics and rendering.

For 1, 3 and 6 robots (``humanoid_sim.world.World``: one MuJoCo model, the robots at their
default start poses holding their standing crouch), each in a fresh child process,
``--repeat`` times interleaved, medians printed with ratios against the one-robot world of
the same run:

* ``physics``: process CPU per 10 ms world step (5 MuJoCo steps of 2 ms, all robots'
  servos slewed and their contacts solved);
* ``render``: process CPU per camera frame (320x240, the software rasteriser's worker
  threads included), every robot's head camera drawn from the ONE offscreen GL context the
  world component uses, and what that costs per 10 ms step when every camera runs at 30 Hz
  (frames per step = robots x 0.3: the upper bound, as the component renders a camera only
  while someone wants its frames);
* ``render_separate``: the same frames from one GL context per camera, as one-robot
  simulators side by side would draw them: what sharing the context saves;
* ``render_fine``: the same frames at MuJoCo's default tessellation (the one-robot
  simulator's), what the world's coarser ``RENDER_QUALITY`` saves.

The sum per step against 10 ms is the real-time factor physics and cameras alone would allow
(bus emulation and robot software come on top). Run:
``source scripts/env.sh && python bench/world_bench.py`` (``--quick`` for a smoke run).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run as a script: the repo root holds the bench package
from bench._children import run_child  # noqa: E402

DEFAULT_OUT = ROOT / "bench" / "out" / "world_bench.json"
SIZES = (1, 3, 6)
#: One team, then both: blue first, as ``--robots 3`` and ``3v3`` would field them.
ORDER = ("blue1", "blue2", "blue3", "red1", "red2", "red3")
STEP_S = 0.01
CAMERA_HZ = 30.0
WIDTH, HEIGHT = 320, 240
#: MuJoCo's default ``<visual><quality>`` (numslices, numstacks, numquads); the world uses
#: ``humanoid_sim.world.RENDER_QUALITY``.
MUJOCO_QUALITY = (28, 16, 4)


def measure(robots: int, *, steps: int, frames: int) -> dict[str, float]:
    import numpy as np

    from humanoid_sim.joints import JOINTS
    from humanoid_sim.mujoco_plant import NO_LOAD_SPEED_RAD_S
    from humanoid_sim.render import OffscreenRenderer
    from humanoid_sim.soccer.motion import STANCE
    from humanoid_sim.world import DEFAULT_START, World

    names = ORDER[:robots]
    world = World({name: DEFAULT_START[name] for name in names})
    for plant in world.robots.values():
        for dxl_id, joint in JOINTS.items():
            plant.command(dxl_id, torque=True, goal_rad=STANCE[joint],
                          max_speed_rad_s=NO_LOAD_SPEED_RAD_S)
    world.step(1.0)  # settled in the crouch: contacts as in a game's standing phases
    cpu = time.process_time()
    for _ in range(steps):
        world.step(STEP_S)
    physics_ms = (time.process_time() - cpu) / steps * 1e3
    standing = sum(p.torso_height() > 0.3 for p in world.robots.values())

    out = np.empty((HEIGHT, WIDTH, 3), dtype=np.uint8)
    cameras = [f"{name}/head_camera" for name in names]

    def render_ms(renderers: list[OffscreenRenderer]) -> float:
        for renderer, camera in zip(renderers, cameras, strict=True):  # warm up each
            renderer.render(world.data, out, camera=camera)
        cpu = time.process_time()
        for _ in range(frames):
            for renderer, camera in zip(renderers, cameras, strict=True):
                renderer.render(world.data, out, camera=camera)
        return (time.process_time() - cpu) / (frames * len(cameras)) * 1e3

    shared = OffscreenRenderer(world.model, width=WIDTH, height=HEIGHT)
    shared_ms = render_ms([shared] * robots)
    shared.close()
    separate = [OffscreenRenderer(world.model, width=WIDTH, height=HEIGHT) for _ in names]
    separate_ms = render_ms(separate)
    for renderer in separate:
        renderer.close()
    quality = world.model.vis.quality  # what the world's coarser tessellation saves
    quality.numslices, quality.numstacks, quality.numquads = MUJOCO_QUALITY
    fine = OffscreenRenderer(world.model, width=WIDTH, height=HEIGHT)
    fine_ms = render_ms([fine] * robots)
    fine.close()
    frames_per_step = robots * CAMERA_HZ * STEP_S
    return {"physics_ms": physics_ms, "render_frame_ms": shared_ms,
            "render_ms": shared_ms * frames_per_step,
            "render_separate_frame_ms": separate_ms, "render_fine_frame_ms": fine_ms,
            "standing": float(standing)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", type=int, default=300, help="10 ms world steps per run")
    ap.add_argument("--frames", type=int, default=40, help="frames per camera per run")
    ap.add_argument("--quick", action="store_true", help="1 short run each: a smoke test")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.steps, args.frames = 1, 20, 3
    if args.child:
        task = json.loads(args.child)
        print(json.dumps(measure(task["robots"], steps=task["steps"], frames=task["frames"])))
        return 0

    runs: dict[int, list[dict[str, float]]] = {n: [] for n in SIZES}
    for _ in range(args.repeat):  # interleaved, so drifting machine load hits all alike
        for n in SIZES:
            task = {"kind": "world", "robots": n, "steps": args.steps, "frames": args.frames}
            runs[n].append(run_child(__file__, task, name="world_bench"))

    def med(n: int, key: str) -> float:
        return statistics.median(r[key] for r in runs[n])

    summary: dict[str, Any] = {}
    print(f"medians of {args.repeat} run(s); CPU per {STEP_S * 1e3:g} ms world step, every "
          f"camera at {CAMERA_HZ:g} Hz ({WIDTH}x{HEIGHT}); ratios against 1 robot")
    print("robots | physics ms/step (x1) | render ms/frame, one context (separate; fine) | "
          "render ms/step (x1) | total ms/step | RTF bound")
    for n in SIZES:
        physics, render = med(n, "physics_ms"), med(n, "render_ms")
        total = physics + render
        row = {"physics_ms": physics, "physics_ratio": physics / med(1, "physics_ms"),
               "render_frame_ms": med(n, "render_frame_ms"),
               "render_separate_frame_ms": med(n, "render_separate_frame_ms"),
               "render_fine_frame_ms": med(n, "render_fine_frame_ms"),
               "render_ms": render, "render_ratio": render / med(1, "render_ms"),
               "total_ms": total, "rtf_bound": STEP_S * 1e3 / total,
               "standing": med(n, "standing")}
        summary[str(n)] = row
        print(f"{n:6d} | {physics:7.2f} ({row['physics_ratio']:.2f}) | "
              f"{row['render_frame_ms']:6.2f} ({row['render_separate_frame_ms']:.2f}; "
              f"{row['render_fine_frame_ms']:.2f}) | "
              f"{render:6.2f} ({row['render_ratio']:.2f}) | {total:6.2f} | "
              f"{row['rtf_bound']:.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "runs": runs}, indent=1))
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
