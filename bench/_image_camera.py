"""A light robot for the image-view benchmark: a synthetic 30 fps 320x240 camera.

The simulator's camera shares the machine with MuJoCo physics and the servo bus, so on a
loaded machine it runs below 30 fps; this camera draws a moving orange ball on green with
OpenCV instead, so the benchmark measures the GUI's pipeline, not the simulator. Composed
with the real ball detector (its debug drawings) and the real JPEG compressor, as on the
simulated robot. ``python bench/_image_camera.py --namespace /robot`` until Ctrl-C.
"""

from __future__ import annotations

import argparse
import array
import math

import cv2
import numpy as np
from sensor_msgs.msg import Image

from debug_probes import JpegCompressor
from efficient_comm import Container, to_msg
from efficient_comm.handle import NodeHandle
from humanoid_sim.soccer.vision import BallDetector
from throttle_publisher import ThrottledPublisher

WIDTH, HEIGHT, RATE_HZ = 320, 240, 30.0


class SyntheticCamera:
    """``camera/image_raw`` at 30 Hz, rendered only when wanted (a throttled publisher)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.out = ThrottledPublisher(node, Image, "camera/image_raw", qos=2)
        self.frames = 0
        node.create_timer(1.0 / RATE_HZ, self.tick)

    def tick(self) -> None:
        self.frames += 1
        if not self.out.wants():
            self.out.skip()
            return
        t = self.frames / RATE_HZ
        pixels = np.full((HEIGHT, WIDTH, 3), (40, 140, 40), dtype=np.uint8)
        cv2.line(pixels, (0, 180), (WIDTH, 180), (255, 255, 255), 3)
        centre = (int(WIDTH / 2 + 100 * math.sin(t)), int(HEIGHT / 2 + 50 * math.cos(1.3 * t)))
        cv2.circle(pixels, centre, 14, (255, 115, 0), -1)
        image = Image(height=HEIGHT, width=WIDTH, encoding="rgb8", step=WIDTH * 3)
        image.header.stamp = to_msg(self.node.clock.now_ns())
        image.header.frame_id = "camera"
        image.data = array.array("B", pixels.tobytes())
        self.out.publish(image)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--namespace", default="/robot")
    args = parser.parse_args()
    with Container("camera", namespace=args.namespace,
                   stats_namespace=args.namespace) as container:
        for cls, name in ((SyntheticCamera, "camera"), (BallDetector, "ball_detector"),
                          (JpegCompressor, "jpeg_compressor")):
            container.add(cls, name=name, namespace=args.namespace)
        print("camera ready", flush=True)
        container.spin()


if __name__ == "__main__":
    main()
