"""Offscreen camera images from MuJoCo on a machine without a display or GPU.

EGL (Mesa's software rasteriser does without a GPU) is tried first, OSMesa second. The choice
is made once per process and cannot change afterwards: PyOpenGL binds one platform on first
use. :func:`gl_backend` therefore probes EGL in a child process before this process commits,
so a broken EGL install falls back to OSMesa instead of failing half-initialised.
``MUJOCO_GL=egl|osmesa`` skips the probe.
"""

from __future__ import annotations

import array
import ctypes.util
import importlib
import os
import subprocess
import sys
import threading
import time
from functools import cache
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from .errors import RenderError

_PROBE = (
    "from mujoco.egl import GLContext\n"
    "c = GLContext(8, 8)\n"
    "c.make_current()\n"
    "c.free()\n"
)


@cache
def gl_backend() -> str:
    """``"egl"`` or ``"osmesa"``: what this process renders with. Raises RenderError."""
    chosen = os.environ.get("MUJOCO_GL", "").lower()
    if chosen in ("egl", "osmesa"):
        return chosen
    try:
        probe = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, timeout=60,
                               env={**os.environ, "PYOPENGL_PLATFORM": "egl"}, check=False)
        egl_error = probe.stderr.decode(errors="replace").strip().splitlines()[-1:]
        if probe.returncode == 0:
            return "egl"
    except (OSError, subprocess.TimeoutExpired) as exc:
        egl_error = [str(exc)]
    if ctypes.util.find_library("OSMesa"):
        return "osmesa"
    raise RenderError(
        f"no offscreen OpenGL: EGL failed ({' '.join(egl_error) or 'unknown error'}) and "
        "OSMesa is not installed (Debian: libegl1 libegl-mesa0, or libosmesa6)"
    )


class OffscreenRenderer:
    """Renders any camera of a model into RGB arrays (row 0 at the top, as images are
    stored), all from one offscreen GL context.

    One context serves every robot of a shared world: a context costs its framebuffers and
    the model's uploaded textures and meshes, and switching between contexts costs a flush,
    while the cameras differ only in the view. Shadows and reflections are off: they cost
    ~10x the frame time in a software rasteriser and do not matter to colour-based ball
    detection.

    ``samples`` sets the context's multisampling (antialiasing) for this renderer only (the
    model's own setting is restored at once): the match video asks for its own, while
    the robots' cameras keep the model's. ``maxgeom`` bounds the scene (a whole field of
    robots seen from above needs more than one robot's camera).
    """

    def __init__(self, model: mujoco.MjModel, *, width: int, height: int,
                 samples: int | None = None, maxgeom: int = 2000) -> None:
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise RenderError(
                f"{width}x{height} exceeds the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight} "
                "(<visual><global offwidth offheight>)"
            )
        backend = gl_backend()
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
        try:
            gl: Any = importlib.import_module(f"mujoco.{backend}").GLContext(width, height)
        except Exception as exc:
            raise RenderError(f"cannot create a {backend} OpenGL context: {exc}") from exc
        # The context takes its multisampling from the model when it is made.
        model_samples = model.vis.quality.offsamples
        try:
            gl.make_current()
            if samples is not None:
                model.vis.quality.offsamples = samples
            context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
        except Exception as exc:
            gl.free()
            raise RenderError(f"cannot set up {backend} rendering: {exc}") from exc
        finally:
            model.vis.quality.offsamples = model_samples
        self._gl: Any = gl
        self._context: mujoco.MjrContext | None = context
        self.backend = backend
        self.width, self.height = width, height
        self._model = model
        self._scene = mujoco.MjvScene(model, maxgeom=maxgeom)
        self._option = mujoco.MjvOption()
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._flipped = np.empty((height, width, 3), dtype=np.uint8)
        #: Frames rendered, per camera name: what consumers asked for.
        self.frames: dict[str, int] = {}
        self._ids: dict[str, int] = {}

    def camera_id(self, camera: str) -> int:
        """The model's id of ``camera``; RenderError if the model has no such camera."""
        if camera not in self._ids:
            try:
                self._ids[camera] = int(self._model.camera(camera).id)
            except KeyError:
                raise RenderError(f"no camera {camera!r} in the model") from None
        return self._ids[camera]

    @property
    def scene(self) -> mujoco.MjvScene:
        """The last rendered scene (its GL cameras give a free camera's calibration)."""
        return self._scene

    def render(self, data: mujoco.MjData, out: npt.NDArray[np.uint8], *,
               camera: str | mujoco.MjvCamera) -> None:
        """Draw ``camera``'s view of ``data`` into ``out`` (height x width x 3, uint8):
        a camera of the model by name, or a free ``MjvCamera`` (a view from anywhere)."""
        if self._context is None:
            raise RenderError("the renderer is closed")
        self.update_scene(data, camera=camera, scene=self._scene)
        self.draw(self._scene, out)
        if isinstance(camera, str):
            self.frames[camera] = self.frames.get(camera, 0) + 1

    def update_scene(self, data: mujoco.MjData, *, camera: str | mujoco.MjvCamera,
                     scene: mujoco.MjvScene) -> None:
        """Take ``camera``'s view of ``data`` into ``scene`` (one made for this model):
        everything a draw needs, copied, so ``data`` may step on at once. No GL: any
        thread may call it."""
        view = camera
        if isinstance(camera, str):
            view = mujoco.MjvCamera()
            view.type = mujoco.mjtCamera.mjCAMERA_FIXED
            view.fixedcamid = self.camera_id(camera)
        mujoco.mjv_updateScene(self._model, data, self._option, None, view,
                               mujoco.mjtCatBit.mjCAT_ALL, scene)

    def draw(self, scene: mujoco.MjvScene, out: npt.NDArray[np.uint8]) -> None:
        """Draw a scene taken by :meth:`update_scene` into ``out``, on the thread that made
        this renderer (a GL context is current on one thread)."""
        if self._context is None:
            raise RenderError("the renderer is closed")
        self._gl.make_current()
        scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        mujoco.mjr_render(self._rect, scene, self._context)
        mujoco.mjr_readPixels(self._flipped, None, self._rect, self._context)
        np.copyto(out, self._flipped[::-1])  # OpenGL's rows run bottom-up

    def close(self) -> None:
        """Free the GL context; a second call does nothing (a double free would crash)."""
        if self._context is None:
            return
        context, self._context = self._context, None
        context.free()
        self._gl.free()


class RenderThread:
    """Cameras of one model drawn on a thread of its own: :meth:`capture` takes the views
    on the caller's thread, :meth:`collect` returns the frames once drawn.

    Why: a world of six robots draws six frames each camera period, 6-7 ms each in a
    software rasteriser, and did so on the thread that steps the physics and runs the
    lockstep barrier: a third of that thread's time in a 3v3 match, while the robots
    waited for it. Only taking a view needs the ``MjData`` (:meth:`OffscreenRenderer.
    update_scene` copies what a draw needs), and MuJoCo's draw calls release the GIL, so
    the caller steps on, publishes and waits for its robots while this thread draws.

    The thread makes the renderer (a GL context is current on one thread only); a renderer
    that cannot be made raises RenderError here, in the constructor. One batch is in flight
    at a time: :meth:`capture` again before :meth:`collect` is refused.
    """

    def __init__(self, model: mujoco.MjModel, *, width: int, height: int,
                 name: str = "render") -> None:
        self.width, self.height = width, height
        self._model = model
        #: Frames drawn, per camera name.
        self.frames: dict[str, int] = {}
        #: The drawing thread's CPU and wall time in draws (the rasteriser's threads apart).
        self.draw_cpu_ns = 0
        self.draw_ns = 0
        self._scenes: dict[str, mujoco.MjvScene] = {}
        self._batch: list[str] = []
        self._images: dict[str, array.array[int]] = {}
        self._error: BaseException | None = None
        self._work = threading.Condition()
        self._job: list[str] | None = None  # set by capture, cleared by the thread
        self._closing = False
        self._ready = threading.Event()
        self._renderer: OffscreenRenderer | None = None
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()
        self._ready.wait()
        renderer = self._made()
        if renderer is None:
            self._thread.join()
            raise self._error if isinstance(self._error, RenderError) else RenderError(
                f"cannot start the render thread: {self._error}")
        self.backend: str = renderer.backend
        self._error = None

    def _made(self) -> OffscreenRenderer | None:
        return self._renderer  # set by the thread

    def pending(self) -> bool:
        """A batch is captured and not yet collected."""
        return bool(self._batch)

    def capture(self, data: mujoco.MjData, cameras: list[str]) -> None:
        """Take each camera's view of ``data`` now and hand the batch to the thread."""
        if self._renderer is None:
            raise RenderError("the render thread is closed")
        if self._batch:
            raise RenderError("a batch is still being drawn: collect it first")
        for camera in cameras:
            scene = self._scenes.get(camera)
            if scene is None:
                scene = self._scenes[camera] = mujoco.MjvScene(self._model, maxgeom=2000)
            self._renderer.update_scene(data, camera=camera, scene=scene)
        self._batch = list(cameras)
        with self._work:
            self._job = self._batch
            self._work.notify()

    def collect(self) -> dict[str, array.array[int]]:
        """The captured batch's frames (rgb8, rows top-down, each a buffer of its own that
        a message may keep), once drawn; {} if nothing was captured."""
        with self._work:
            self._work.wait_for(lambda: self._job is None)
        if self._error is not None:
            error, self._error = self._error, None
            self._batch = []
            raise RenderError(f"drawing failed: {error}") from error
        images, self._images, self._batch = self._images, {}, []
        return images

    def _run(self) -> None:
        try:
            renderer = OffscreenRenderer(self._model, width=self.width, height=self.height)
        except BaseException as exc:  # re-raised by the constructor
            self._error = exc
            self._ready.set()
            return
        self._renderer = renderer
        self._ready.set()
        try:
            while True:
                with self._work:
                    self._work.wait_for(lambda: self._job is not None or self._closing)
                    if self._job is None:
                        return
                    job = self._job
                started, cpu = time.perf_counter_ns(), time.thread_time_ns()
                try:
                    for camera in job:
                        buffer = array.array("B", bytes(self.width * self.height * 3))
                        out = np.frombuffer(buffer, dtype=np.uint8).reshape(
                            self.height, self.width, 3)
                        renderer.draw(self._scenes[camera], out)
                        self._images[camera] = buffer
                        self.frames[camera] = self.frames.get(camera, 0) + 1
                except Exception as exc:  # the caller's collect raises it
                    self._error = exc
                self.draw_cpu_ns += time.thread_time_ns() - cpu
                self.draw_ns += time.perf_counter_ns() - started
                with self._work:
                    self._job = None
                    self._work.notify_all()
        finally:
            renderer.close()

    def close(self) -> None:
        """Finish the batch being drawn, stop the thread, free the GL context (idempotent)."""
        with self._work:
            self._closing = True
            self._work.notify_all()
        self._thread.join()
        self._renderer = None


class OffscreenCamera:
    """One camera on a renderer of its own: the one-robot simulator's head camera."""

    def __init__(self, model: mujoco.MjModel, *, camera: str, width: int, height: int) -> None:
        self.renderer = OffscreenRenderer(model, width=width, height=height)
        try:
            self.renderer.camera_id(camera)
        except RenderError:
            self.renderer.close()
            raise
        self.camera = camera
        self.backend = self.renderer.backend
        self.width, self.height = width, height

    def render(self, data: mujoco.MjData, out: npt.NDArray[np.uint8]) -> None:
        """Draw the camera's view of ``data`` into ``out`` (height x width x 3, uint8)."""
        self.renderer.render(data, out, camera=self.camera)

    def close(self) -> None:
        """Free the GL context; a second call does nothing (a double free would crash)."""
        self.renderer.close()
