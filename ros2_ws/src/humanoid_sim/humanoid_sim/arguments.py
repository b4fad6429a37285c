"""What the demo's and the match's command lines share, importable without the simulator.

Nothing here imports MuJoCo, rclpy or a container: ``python -m humanoid_sim.demo --seed x``
and ``--help`` answer in the time Python takes to start, before the simulation (about two
seconds of imports) is loaded, as a user typing a command expects.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
from collections.abc import Callable, Sequence
from typing import Literal, NoReturn

from soccer_field import KIDSIZE

EXIT_OK, EXIT_BUG, EXIT_USAGE, EXIT_FELL = 0, 1, 2, 3
#: Seed 0's start: the kick-off (robot in its own half facing the opponent goal, the ball
#: on the centre mark); other seeds draw theirs (:func:`start_positions`).
KICK_OFF_POSE, KICK_OFF_BALL = (-1.0, 0.5, 0.0), (0.0, 0.0)
#: Options whose value may start with a minus sign (``--ball -0.5,0``).
SIGNED_OPTIONS = ("--robot-pose", "--ball")
Transport = Literal["shm", "dds"]
#: ``--split``'s transports of the camera image between the robot's two processes
#: (:mod:`.split`): shared memory, or DDS as the baseline.
TRANSPORTS: tuple[Transport, ...] = ("shm", "dds")


def start_positions(seed: int) -> tuple[tuple[float, float, float], tuple[float, float]]:
    """Where the robot (x, y, heading) and the ball (x, y) start for ``seed``.

    Seed 0 is the kick-off (:data:`KICK_OFF_POSE`, :data:`KICK_OFF_BALL`). Other seeds
    draw a start a game can have: the robot in its own half, at least 0.5 m inside the
    lines and off the halfway line, facing anywhere; the ball in the middle of the field
    (within 1.5 m of the centre mark in x and y, clear of the penalty areas) and at least
    0.6 m from the robot, so every start asks for a walk before the kick.
    """
    if seed == 0:
        return KICK_OFF_POSE, KICK_OFF_BALL
    rng = random.Random(f"soccer_demo start {seed}")
    while True:
        half_l, half_w = KIDSIZE.half_length, KIDSIZE.half_width
        pose = (rng.uniform(-half_l + 0.5, -0.5), rng.uniform(-half_w + 0.5, half_w - 0.5),
                rng.uniform(-math.pi, math.pi))
        ball = (rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5))
        if math.dist(pose[:2], ball) >= 0.6:
            return pose, ball


def finite_number(*, low: float = -math.inf, high: float = math.inf, low_open: bool = False,
            high_open: bool = False, what: str) -> Callable[[str], float]:
    """A finite number within [low, high] (bounds excluded where ``*_open``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        inside = ((value > low if low_open else value >= low)
                  and (value < high if high_open else value <= high))
        if not math.isfinite(value) or not inside:
            raise argparse.ArgumentTypeError(f"{text!r}: need {what}")
        return value
    return parse


def field_position(count: int, what: str) -> Callable[[str], list[float]]:
    """``count`` comma-separated finite numbers, x and y on the field."""
    def parse(text: str) -> list[float]:
        try:
            values = [float(part) for part in text.split(",")]
        except ValueError:
            values = []
        if len(values) != count or not all(map(math.isfinite, values)):
            raise argparse.ArgumentTypeError(f"{text!r}: need {what}, {count} numbers "
                                             f"separated by commas")
        half_l, half_w = KIDSIZE.half_length, KIDSIZE.half_width
        if abs(values[0]) > half_l or abs(values[1]) > half_w:
            raise argparse.ArgumentTypeError(
                f"{text!r} is off the field: it is {2 * half_l:g} x {2 * half_w:g} m, "
                f"x within +-{half_l:g}, y within +-{half_w:g} (origin the centre mark)")
        return values
    return parse


class DemoArguments(argparse.ArgumentParser):
    """The demo's parser: a bad argument is one line (``soccer_demo: error: ...``) and
    exit status 2, and values of :data:`SIGNED_OPTIONS` may start with a minus sign."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")

    def parse_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                   namespace: None = None) -> argparse.Namespace:
        # argparse takes "-0.5,0" for an option (only plain negative numbers are values):
        # glue such a value to its option, as "--ball=-0.5,0" is read.
        given = list(sys.argv[1:] if args is None else args)
        joined: list[str] = []
        for arg in given:
            if joined and joined[-1] in SIGNED_OPTIONS and arg.startswith("-"):
                joined[-1] = f"{joined[-1]}={arg}"
            else:
                joined.append(arg)
        return super().parse_args(joined)


def namespace_arg(text: str) -> str:
    """``--namespace``: an absolute ROS namespace (a relative one gets its leading slash)."""
    from rclpy.validate_namespace import validate_namespace  # rclpy only when given

    namespace = text if text.startswith("/") else "/" + text
    try:
        validate_namespace(namespace)
    except Exception as exc:  # rclpy's InvalidNamespaceException, with a caret line
        reason = str(exc).splitlines()[0].rstrip(":")
        raise argparse.ArgumentTypeError(f"{text!r}: {reason}") from None
    return namespace


