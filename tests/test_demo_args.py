"""The soccer demo's command line as a user types it: negative coordinates, the start drawn
from the seed, and every bad argument refused with one line and exit status 2."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env
from humanoid_sim.demo import EXIT_USAGE, KICK_OFF_BALL, KICK_OFF_POSE, start_positions

DEMO = [sys.executable, "-m", "humanoid_sim.demo"]


def run_demo(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*DEMO, *args], env=ros_env(isolated_domain_id()), cwd=cwd,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(("args", "says"), [
    (["--stats-period", "-1"], "--stats-period"),
    (["--duration", "-5"], "--duration"),
    (["--duration", "nan"], "--duration"),
    (["--line-noise", "1.5"], "--line-noise"),
    (["--line-noise", "1"], "--line-noise"),
    (["--push-at=-1"], "--push-at"),
    (["--push-newtons", "inf"], "--push-newtons"),
    (["--robot-pose", "7,0,0"], "9 x 6 m"),
    (["--robot-pose", "-3,-3.2,0"], "9 x 6 m"),
    (["--ball", "-4.6,0"], "9 x 6 m"),
    (["--ball", "-0.5"], "--ball"),
    (["--seed", "x"], "--seed"),
    (["--no-such-option"], "unrecognized"),
    (["--split", "--lockstep"], "--split runs two processes in real time"),
    (["--split", "dds", "--no-dds"], "not with --no-dds"),
    (["--split", "udp"], "--split"),
])
def test_a_bad_argument_is_one_line_and_exit_status_2(tmp_path: Path, args: list[str],
                                                      says: str) -> None:
    result = run_demo(args, tmp_path)
    assert result.returncode == EXIT_USAGE == 2, result.stdout + result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("soccer_demo: error:"), result.stderr
    assert says in lines[0], lines[0]
    assert result.stdout == "" and not list(tmp_path.iterdir())  # nothing started


def report_start(text: str) -> tuple[list[float], list[float]]:
    found = re.search(r"\| start \| robot at (\S+) \(x, y, heading\), ball at (\S+) \|", text)
    assert found is not None, text
    return ([float(v) for v in found.group(1).split(",")],
            [float(v) for v in found.group(2).split(",")])


def test_negative_coordinates_as_the_docs_write_them_and_no_live_lines(tmp_path: Path) -> None:
    result = run_demo(["--lockstep", "--no-dds", "--duration", "0.3", "--stats-period", "0",
                       "--ball", "-0.5,0", "--robot-pose", "-3,-1,0", "--report", "r.md"],
                      tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert report_start((tmp_path / "r.md").read_text()) == ([-3, -1, 0], [-0.5, 0])
    assert "sim s" not in result.stdout  # --stats-period 0: no live lines, and it ends


def test_the_seed_draws_the_start(tmp_path: Path) -> None:
    result = run_demo(["--lockstep", "--no-dds", "--duration", "0.1", "--seed", "7",
                       "--stats-period", "0.1", "--report", "r.md"], tmp_path)
    # In 0.1 s the ball may not have been seen yet (exit status 1): the start is the point.
    assert "report written" in result.stdout and "Traceback" not in result.stderr, (
        result.stdout + result.stderr)
    pose, ball = report_start((tmp_path / "r.md").read_text())
    want_pose, want_ball = start_positions(7)
    assert pose == pytest.approx(want_pose, abs=1e-5) and ball == pytest.approx(want_ball,
                                                                               abs=1e-5)
    assert (tuple(pose), tuple(ball)) != (KICK_OFF_POSE, KICK_OFF_BALL)


def test_starts_drawn_from_seeds_differ_and_follow_the_rules() -> None:
    starts = {seed: start_positions(seed) for seed in range(1, 21)}
    assert start_positions(0) == (KICK_OFF_POSE, KICK_OFF_BALL)
    assert len(set(starts.values())) == len(starts)
    assert start_positions(5) == starts[5]  # the same seed, the same start
    for (x, y, heading), ball in starts.values():
        assert -4.5 < x < 0 and abs(y) < 3 and -math.pi <= heading <= math.pi  # own half
        assert abs(ball[0]) <= 1.5 and abs(ball[1]) <= 1.5  # in the middle of the field
        assert math.dist((x, y), ball) >= 0.6


def test_the_demo_films_the_match_and_refuses_a_video_it_cannot_write(tmp_path: Path) -> None:
    import av

    from humanoid_sim.match_video import read_sidecar

    result = run_demo(["--lockstep", "--no-dds", "--duration", "1", "--stats-period", "0",
                       "--report", "r.md", "--video", "match.mp4"], tmp_path)
    assert "report written" in result.stdout and "Traceback" not in result.stderr, (
        result.stdout + result.stderr)
    sidecar, _ = read_sidecar(tmp_path / "match.mp4")
    with av.open(str(tmp_path / "match.mp4")) as video:
        frames = sum(1 for _ in video.decode(video=0))
    assert frames == sidecar["frames"] >= 12  # 12.5 fps for 1 simulated second
    assert sidecar["start_ns"] == 2_500_000_000  # lockstep starts at 0; the camera is 2.5 s off
    bad = run_demo(["--lockstep", "--no-dds", "--duration", "1", "--video",
                    str(tmp_path / "missing" / "match.mp4")], tmp_path)
    lines = bad.stderr.splitlines()
    assert bad.returncode == EXIT_USAGE and len(lines) == 1, bad.stderr
    assert lines[0].startswith("soccer_demo: error: --video: cannot write the match video")


def _loaded_after(module: str, watched: set[str]) -> set[str]:
    """Which of ``watched`` (top-level packages, or full module names) a fresh Python has
    loaded once it imported ``module``."""
    probe = ("import importlib, json, sys\n"
             f"importlib.import_module({module!r})\n"
             "print(json.dumps(sorted(set(sys.modules) | {m.split('.')[0] for m in sys.modules})))")
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                            timeout=60, check=True).stdout
    return watched & set(json.loads(loaded))


def test_the_command_line_imports_no_simulation() -> None:
    """A bad argument and ``--help`` answer before the simulation is imported (it took about
    two seconds each, a minute for this file's cases on a loaded machine)."""
    assert _loaded_after("humanoid_sim.demo",
                         {"mujoco", "rclpy", "efficient_comm", "cv2", "numpy"}) == set()


def test_a_match_robot_process_imports_no_world() -> None:
    """A robot of the team match runs robot software only: its process does not load the
    world's simulator, renderer or video encoder (it did, for three constants: about two
    seconds of each robot's start on a loaded machine)."""
    assert _loaded_after("humanoid_sim.match_robot",
                         {"mujoco", "av", "humanoid_sim.match_world"}) == set()
