"""Offscreen rendering on either backend, chosen per process (EGL first, OSMesa fallback)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from humanoid_sim.render import gl_backend

_RENDER = """
import json, mujoco, numpy as np
from humanoid_sim.mujoco_plant import MujocoPlant
from humanoid_sim.render import OffscreenCamera
from humanoid_sim.soccer.vision import BallDetector
from efficient_comm.testing import TestHandle
plant = MujocoPlant()
mujoco.mj_forward(plant.model, plant.data)
camera = OffscreenCamera(plant.model, camera="head_camera", width=320, height=240)
image = np.zeros((240, 320, 3), dtype=np.uint8)
camera.render(plant.data, image)
camera.close()
found = BallDetector(TestHandle("d")).find(image)
print(json.dumps({"backend": camera.backend, "ball": found, "mean": float(image.mean())}))
"""


def _render_with(backend: str | None) -> tuple[str, list[float], float]:
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    if backend:
        env["MUJOCO_GL"] = backend
    result = subprocess.run([sys.executable, "-c", _RENDER], capture_output=True, text=True,
                            env=env, timeout=90, check=False)
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout.strip().splitlines()[-1])
    return str(out["backend"]), [float(x) for x in out["ball"]], float(out["mean"])


@pytest.mark.parametrize("backend", ["egl", "osmesa"])
def test_both_backends_render_the_same_scene(backend: str) -> None:
    used, (u, v, r), mean = _render_with(backend)
    assert used == backend
    assert abs(u - 160) < 2 and v > 120 and r > 3  # the ball straight ahead, on the ground
    assert 20 < mean < 200  # a lit scene, not black


def test_without_a_choice_egl_is_probed_first() -> None:
    assert _render_with(None)[0] == "egl" == gl_backend()


def test_one_renderer_draws_a_free_camera_with_its_own_multisampling() -> None:
    """The match video's view: a free camera over the field on the shared renderer, with
    multisampling of its own, the model's setting left as it was for the robots' cameras."""
    import mujoco
    import numpy as np

    from humanoid_sim.mujoco_plant import MujocoPlant
    from humanoid_sim.render import OffscreenRenderer

    plant = MujocoPlant()
    mujoco.mj_forward(plant.model, plant.data)
    before = plant.model.vis.quality.offsamples
    renderer = OffscreenRenderer(plant.model, width=160, height=90, samples=2, maxgeom=4000)
    try:
        assert plant.model.vis.quality.offsamples == before
        free = mujoco.MjvCamera()
        free.type = mujoco.mjtCamera.mjCAMERA_FREE
        free.distance, free.elevation, free.azimuth = 9.0, -65.0, 90.0
        head = np.zeros((90, 160, 3), dtype=np.uint8)
        renderer.render(plant.data, head, camera="head_camera")
        image = np.zeros_like(head)
        renderer.render(plant.data, image, camera=free)
    finally:
        renderer.close()
    assert image.mean() > 10 and not np.array_equal(image, head)
    assert renderer.frames == {"head_camera": 1}  # a free view is nobody's camera frame
    camera = renderer.scene.camera[0]
    assert camera.forward[2] < -0.5  # looking down on the field


def test_the_render_thread_draws_what_a_renderer_draws_while_the_world_steps_on() -> None:
    """RenderThread: the views are taken at capture, so stepping the world before collect
    changes nothing in the frames (pixel for pixel those a renderer draws at capture); one
    batch at a time; closed, it refuses."""
    import mujoco
    import numpy as np

    from humanoid_sim.errors import RenderError
    from humanoid_sim.render import OffscreenRenderer, RenderThread
    from humanoid_sim.world import Pose2D, World

    world = World({"blue1": Pose2D(-1.5, 0.0, 0.0), "red1": Pose2D(1.0, 0.5, 3.1)},
                  ball=(0.0, 0.0))
    mujoco.mj_forward(world.model, world.data)
    cameras = ["blue1/head_camera", "red1/head_camera"]
    expected = {}
    renderer = OffscreenRenderer(world.model, width=64, height=48)
    for camera in cameras:
        expected[camera] = np.zeros((48, 64, 3), dtype=np.uint8)
        renderer.render(world.data, expected[camera], camera=camera)
    renderer.close()

    drawer = RenderThread(world.model, width=64, height=48)
    try:
        drawer.capture(world.data, cameras)
        assert drawer.pending()
        with pytest.raises(RenderError, match="collect it first"):
            drawer.capture(world.data, cameras)
        world.place_ball(x=-1.0, y=0.0)  # in front of blue1 now: not in the captured view
        world.step(0.05)
        frames = drawer.collect()
        assert not drawer.pending() and drawer.frames == {c: 1 for c in cameras}
        for camera in cameras:
            image = np.frombuffer(frames[camera], dtype=np.uint8).reshape(48, 64, 3)
            assert np.array_equal(image, expected[camera]), camera
        assert not np.array_equal(expected[cameras[0]], expected[cameras[1]])
        assert drawer.collect() == {}  # nothing captured since
    finally:
        drawer.close()
    drawer.close()  # idempotent
    with pytest.raises(RenderError, match="closed"):
        drawer.capture(world.data, cameras)
