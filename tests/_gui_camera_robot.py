"""A light robot with the real camera pipeline, for the GUI's image and parameter tests.

``python tests/_gui_camera_robot.py --namespace /robot`` runs one efficient_comm container
(DDS on, statistics on ``<ns>/efficient_comm/stats``, as ``humanoid_sim.demo`` does) holding:

* ``camera`` (:class:`SyntheticCamera`, defined here): ``camera/image_raw`` (rgb8, 320x240,
  30 Hz) showing an orange ball on green turf that moves left and right, and its latched
  ``camera/camera_info``; what the simulator's camera publishes, without MuJoCo;
* ``ball_detector``: humanoid_sim's BallDetector, the real one (its parameters, its vetoes,
  its drawings on ``ball/debug_markers``);
* ``jpeg_compressor``: debug_probes' JpegCompressor, the real one
  (``camera/image_raw/compressed`` through throttle_publisher, ``jpeg_quality``).

The GUI tests about images and parameters check the GUI against these components; the
physics, the walk and the rendering of the full soccer simulation add nothing there but
start-up time and CPU (tests/test_gui_demo_browser.py keeps the real demo end to end).
Prints ``ready`` once the components are loaded; runs until Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import argparse
import math
import sys

import cv2
import numpy as np
from sensor_msgs.msg import CameraInfo, Image

from efficient_comm import ComponentSpec, Container, latched_qos, stop_on_sigterm, to_msg
from efficient_comm.handle import NodeHandle

#: The simulator's head camera: resolution and vertical field of view (degrees).
WIDTH, HEIGHT, FOVY_DEG = 320, 240, 70.0
#: Ball and turf colours (RGB): the ball well inside the detector's default thresholds
#: (OpenCV hue about 14, full saturation and value), the turf outside them.
BALL_RGB, TURF_RGB = (255, 120, 0), (30, 110, 40)
#: How far the turf's grain strays from its colour (per channel): detail for JPEG to keep
#: or drop, as in a rendered scene, so the quality parameter changes the frame's size.
GRAIN = 25


class SyntheticCamera:
    """A camera whose picture is drawn, not rendered: an orange disc on grainy green, moving.

    Parameters: ``rate_hz`` (default 30, the simulator's camera rate). Every frame differs
    (the disc moves a few pixels), so a viewer can tell frames apart as it can the
    simulator's.
    """

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        rate = node.declare_parameter("rate_hz", 30.0, description="frames per second",
                                      range=(1.0, 100.0))
        self.pub = node.create_publisher(Image, "camera/image_raw", qos=2)
        info = node.create_publisher(CameraInfo, "camera/camera_info", qos=latched_qos())
        info.publish(_camera_info())
        self.frames = 0
        grain = np.random.default_rng(7).integers(-GRAIN, GRAIN + 1, (HEIGHT, WIDTH, 3))
        self._turf = np.clip(np.array(TURF_RGB) + grain, 0, 255).astype(np.uint8)
        node.create_timer(1.0 / rate, self._tick)

    def _tick(self) -> None:
        pixels = self._turf.copy()
        u = int(WIDTH / 2 + WIDTH / 4 * math.sin(self.frames * 0.05))
        cv2.circle(pixels, (u, HEIGHT // 2 + 20), 18, BALL_RGB, thickness=-1)
        image = Image(height=HEIGHT, width=WIDTH, encoding="rgb8", step=WIDTH * 3)
        image.header.stamp = to_msg(self.node.clock.now_ns())
        image.header.frame_id = "camera"
        image.data = pixels.tobytes()
        self.frames += 1
        self.pub.publish(image)


def _camera_info() -> CameraInfo:
    f = (HEIGHT / 2) / math.tan(math.radians(FOVY_DEG) / 2)
    info = CameraInfo(width=WIDTH, height=HEIGHT, distortion_model="plumb_bob")
    info.header.frame_id = "camera"
    info.k = [f, 0.0, WIDTH / 2, 0.0, f, HEIGHT / 2, 0.0, 0.0, 1.0]
    info.p = [f, 0.0, WIDTH / 2, 0.0, 0.0, f, HEIGHT / 2, 0.0, 0.0, 0.0, 1.0, 0.0]
    info.d = [0.0] * 5
    return info


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--namespace", default="/robot")
    args = parser.parse_args()
    ns = args.namespace
    stop_on_sigterm()
    try:
        with Container("camera_robot", namespace=ns, stats_namespace=ns) as container:
            container.add(SyntheticCamera, name="camera", namespace=ns)
            # The classes the packages register as components (humanoid_sim::BallDetector,
            # debug_probes::JpegCompressor), by module path as a container file names them.
            for class_path, name in (("humanoid_sim.soccer.vision:BallDetector", "ball_detector"),
                                     ("debug_probes:JpegCompressor", "jpeg_compressor")):
                container.load(ComponentSpec(class_path=class_path, name=name, namespace=ns))
            print("ready", flush=True)
            container.spin()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
