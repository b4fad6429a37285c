"""``ros2 run log_analysis events`` as a user types it: events of a team log printed and
written beside it, a user's generator file taken, and bad input told in one line."""

from __future__ import annotations

import json
import os
import pty
import re
import subprocess
import tty
from pathlib import Path
from typing import Any

import av
from mcap.reader import make_reader
from std_msgs.msg import String

from log_analysis import read_events
from log_analysis.testing import LogBuilder, RobotBag, film_ball, seen_ball


def _events(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ros2", "run", "log_analysis", "events", *map(str, args)],
                          cwd=cwd, capture_output=True, text=True, timeout=60, check=False)


def _log(path: Path) -> LogBuilder:
    with LogBuilder(path) as log:
        for robot, falls in (("blue1", ((0, "standing"), (4, "fallen"), (6, "standing"))),
                             ("red1", ((0, "standing"), (8, "falling")))):
            for t, state in falls:
                log.add(robot, "fall/state", String(data=state), t=t)
        for t in range(11):
            log.add("blue1", "behaviour/state", String(data="kick" if t in (3, 7) else "search"),
                    t=t)
    return log


KICKS = """
from log_analysis import Event, event_generator

@event_generator(topics=["behaviour/state"])
def kicks(m):
    if m.message.data == "kick":
        return [Event("kick", m.log_time_ns, m.log_time_ns, robot=m.robot,
                      description="a kick")]

@event_generator(topics=["behaviour/state"])
def grumpy(m):
    raise RuntimeError("nothing suits me")

GENERATORS = [kicks, grumpy]
"""


def test_events_are_printed_written_beside_the_log_and_a_failing_generator_named(
        tmp_path: Path) -> None:
    built = _log(tmp_path / "match")
    log = tmp_path / "match"
    run = _events(log, "--only", "falls", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    lines = [line.split() for line in run.stdout.splitlines()]
    assert lines[1][:6] == ["4.00", "s", "2.00", "s", "blue1", "fell"]
    assert lines[2][:7] == ["6.00", "s", "0.00", "s", "blue1", "got", "up"]
    assert lines[3][:6] == ["8.00", "s", "2.00", "s", "red1", "fell"]  # to the log's end
    assert "3 events from 1 generators" in run.stdout
    assert "100%" in run.stderr  # the progress line
    sidecar = tmp_path / "match.partial.events.mcap"  # --only: a partial run
    assert [e.name for e in read_events(sidecar)] == ["fell", "got up", "fell"]

    generators = tmp_path / "mine.py"
    generators.write_text(KICKS)
    out = tmp_path / "out.events.mcap"
    run = _events(log, "--only", "falls", "kicks", "grumpy", "--generators", generators,
                  "-o", out, "--start", "2", "--end", "7.5", "--quiet", cwd=tmp_path)
    # The failing generator is named with what it raised; the others' events are all there.
    assert run.returncode == 1
    assert "generator grumpy failed and was left out: RuntimeError: nothing suits me" \
        in run.stderr
    assert "Traceback" not in run.stderr
    assert [(e.name, (e.start_ns - built.ns(0)) / 1e9) for e in read_events(out)] == [
        ("kick", 3.0), ("fell", 4.0), ("got up", 6.0), ("kick", 7.0)]


def test_bad_input_is_one_line_and_a_clear_status(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x00" * 100)
    broken = tmp_path / "broken.py"
    broken.write_text("GENERATORS = [\n")
    _log(tmp_path / "match")
    log = tmp_path / "match"
    for args, status, says in (
            ((tmp_path / "nothing",), 1, "no bag at"),
            ((junk,), 1, "junk.mcap"),
            ((log, "--generators", broken), 1, "broken.py does not run: SyntaxError"),
            ((log, "--only", "nonsense"), 2, "unknown event generator(s) nonsense; known:"),
            ((log, "--start", "abc"), 2, "not a number of seconds"),
            ((log, "--start", "5", "--end", "3"), 2, "is not after --start"),
            ((), 2, "give the LOG")):
        run = _events(*args, cwd=tmp_path)
        assert run.returncode == status, (args, run.stderr)
        assert says in run.stderr, (args, run.stderr)
        assert "Traceback" not in run.stderr
    listed = _events("--list", cwd=tmp_path)
    assert listed.returncode == 0
    assert {line.split()[0] for line in listed.stdout.splitlines()} >= {
        "falls", "ball_lost", "role_oscillation", "long_callbacks", "ball_disagreement",
        "localization_jump", "team_link_silent", "goals"}


def _sync(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ros2", "run", "log_analysis", "sync-video", *map(str, args)],
                          cwd=cwd, capture_output=True, text=True, timeout=90, check=False)


def _kicked(t: float) -> tuple[float, float]:
    """At rest, then rolled 2 m in 2 s, every 10 s."""
    s = t % 10.0
    along = min(max(s - 4.0, 0.0), 2.0)
    return -1.0 + 2.0 * along - 0.5 * along * along, 0.5


def test_sync_video_finds_the_cameras_clock_and_writes_it_beside_the_video(
        tmp_path: Path) -> None:
    log, video = film_ball(tmp_path, _kicked, seconds=30, offset_s=-2.35, drift_ppm=0)
    run = _sync(log, video, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "from the ball track" in run.stdout
    fit = json.loads(Path(f"{video}.sync.json").read_text())
    assert abs(fit["offset_ns"] + 2.35e9) < 50e6  # a quarter of a frame at 5 fps
    # Picked by hand: the first kick seen at 4.0 s of video, 4.0 s into the log.
    run = _sync(log, video, "--anchor", "4.0=4.0", "-o", tmp_path / "hand.json", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert json.loads((tmp_path / "hand.json").read_text())["offset_ns"] == -2_350_000_000
    for args, says in (
            ((log, tmp_path / "none.mp4"), "no video at"),
            ((tmp_path / "nolog", video), "no bag at"),
            ((log, video, "--ball-topic", "/nowhere"), "no ball track on /nowhere"),
            ((log, video, "--anchor", "4.0"), "an anchor is CAMERA=LOG")):
        run = _sync(*args, cwd=tmp_path)
        assert run.returncode in (1, 2), (args, run.stderr)
        assert says in run.stderr, (args, run.stderr)
        assert "Traceback" not in run.stderr


def test_augment_fits_the_clock_when_needed_and_writes_the_augmented_video(
        tmp_path: Path) -> None:
    log, video = film_ball(tmp_path, _kicked, seconds=12, offset_s=0.8, drift_ppm=0,
                           robots={"blue1": lambda t: (-2.0 + 0.1 * t, 0.0, 0.3)})
    run = _augment(log, video, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "fitting the video's clock first" in run.stderr
    assert "60 frames of 480x294 with blue1" in run.stdout
    out = tmp_path / "match.augmented.mp4"
    with av.open(str(out)) as container:
        assert sum(1 for _ in container.decode(video=0)) == 60
    assert Path(f"{video}.sync.json").exists()
    again = _augment(log, video, cwd=tmp_path)  # the output exists: refused, kept
    assert again.returncode == 1 and "exists already" in again.stderr
    assert "Traceback" not in again.stderr


def _augment(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ros2", "run", "log_analysis", "augment", *map(str, args)],
                          cwd=cwd, capture_output=True, text=True, timeout=90, check=False)


def test_compare_two_ball_detectors_on_one_log_as_a_user_types_it(tmp_path: Path) -> None:
    frames = [(1.0 + k / 2, -10.0 + k, 4 <= k < 8) for k in range(16)]
    log = seen_ball(tmp_path / "log", robot="blue1", frames=frames)
    run = subprocess.run(
        ["ros2", "run", "log_analysis", "compare", str(log), "--robot", "blue1",
         "--a", "colour=humanoid_sim::BallDetector", "--b", "blob=humanoid_sim::BlobBallDetector",
         "--set", "b.min_fill=0.4", "-o", str(tmp_path / "report")],
        cwd=tmp_path, capture_output=True, text=True, timeout=90, check=False)
    assert run.returncode == 0, run.stderr
    # A hit needs the bearing within the tolerance: the colour detector's 4 bars are none.
    assert "| hits (ball in view, within 2°) | 75% | 100% |" in run.stdout, run.stdout
    assert "16 images (16 with the ball in view by the ground truth, 0 out of view, 0 " \
        "without ground truth)" in run.stdout
    assert "They agree (both nothing, or within 2°) on 75% of the images" in run.stdout
    assert "Callback times are single-shot" in run.stdout
    assert (tmp_path / "report" / "report.md").exists()
    disagreements = read_events(tmp_path / "report" / "disagreements.events.mcap")
    assert len(disagreements) == 4
    bad = subprocess.run(
        ["ros2", "run", "log_analysis", "compare", str(log), "--robot", "blue1",
         "--a", "colour=humanoid_sim::BallDetector", "--b", "blob", "-o", str(tmp_path / "x")],
        cwd=tmp_path, capture_output=True, text=True, timeout=90, check=False)
    assert bad.returncode == 2 and "a variant is LABEL=COMPONENT" in bad.stderr



def test_compare_settings_are_checked_and_converted_and_no_disagreement_is_none(
        tmp_path: Path) -> None:
    """``--set b.no_such_param=1`` was taken silently and ``b.min_fill=1`` refused as not a
    DOUBLE; a report without disagreements said "- nowhere"."""
    log = seen_ball(tmp_path / "log", robot="blue1",
                    frames=[(1.0 + k / 2, -4.0 + k, False) for k in range(6)])

    def compare(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            ["ros2", "run", "log_analysis", "compare", str(log), "--robot", "blue1", "--a",
             "one=humanoid_sim::BlobBallDetector", "--b", "two=humanoid_sim::BlobBallDetector",
             "--quiet", *args], cwd=tmp_path, capture_output=True, text=True, timeout=90,
            check=False)

    run = compare("--set", "b.no_such_param=1", "-o", "x")
    assert run.returncode == 1
    assert re.fullmatch(r"compare: error: variant two \(humanoid_sim::BlobBallDetector\) has "
                        r"no parameter no_such_param; its parameters: .*min_fill.*\n",
                        run.stderr), run.stderr
    run = compare("--set", "b.min_fill=0", "-o", "y")
    assert run.returncode == 0, run.stderr
    assert "(min_fill=0)" in run.stdout  # an int taken for the double, as ros2 param set
    report = (tmp_path / "y" / "report.md").read_text()
    assert report.endswith("## Where they disagree most\n\nnone: they agree on every image\n")


def _on_terminal(args: list[str], cwd: Path) -> tuple[int, str]:
    """Run ``args`` with standard error on a terminal (a pty in raw mode, so what the
    command writes arrives unchanged), as a user at a shell sees it; returns the status and
    what it wrote there."""
    master, slave = pty.openpty()
    tty.setraw(slave)
    with subprocess.Popen(args, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                          stderr=slave) as child:
        os.close(slave)
        chunks = []
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO: the child closed its end
                break
            if not chunk:
                break
            chunks.append(chunk)
        os.close(master)
        status = child.wait(timeout=90)
    return status, b"".join(chunks).decode()


def _progress_lines(stderr: str, label: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith(f"{label}: [")]


def test_sync_video_and_compare_show_progress_to_100_percent_on_a_finished_line(
        tmp_path: Path) -> None:
    log, video = film_ball(tmp_path, _kicked, seconds=30, offset_s=-2.35, drift_ppm=0)
    images = seen_ball(tmp_path / "images", robot="blue1",
                       frames=[(1.0 + k / 4, -10.0 + k / 3, False) for k in range(60)])
    commands = {
        "sync-video": ["ros2", "run", "log_analysis", "sync-video", str(log), str(video),
                       "-o", str(tmp_path / "fit.json")],
        "compare": ["ros2", "run", "log_analysis", "compare", str(images), "--robot", "blue1",
                    "--a", "colour=humanoid_sim::BallDetector",
                    "--b", "blob=humanoid_sim::BlobBallDetector", "-o", str(tmp_path / "r")]}
    for label, args in commands.items():
        # Into a file or a CI log: a line per tenth, rising, the last at 100 %.
        run = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=90,
                             check=False)
        assert run.returncode == 0, run.stderr
        lines = _progress_lines(run.stderr, label)
        assert len(lines) >= 3, run.stderr
        percents = [int(line.split("]")[1].split("%")[0]) for line in lines]
        assert percents == sorted(percents) and percents[-1] == 100, run.stderr
        assert run.stderr.endswith("\n")
        quiet = subprocess.run([*args, "--quiet"], cwd=tmp_path, capture_output=True,
                               text=True, timeout=90, check=False)
        assert quiet.returncode == 0, quiet.stderr
        assert _progress_lines(quiet.stderr, label) == []
        # On a terminal: one line redrawn in place, ending at 100 % with a newline.
        status, shown = _on_terminal(args, tmp_path)
        assert status == 0, shown
        assert shown.count("\r") >= 3, shown
        last = shown.rsplit("\r", 1)[1]
        assert last.startswith(f"{label}: [{'#' * 30}] 100%"), shown
        assert last.endswith("\n") and last.count("\n") == 1, shown


def test_events_of_several_robots_bags_are_those_of_their_merged_log(tmp_path: Path) -> None:
    """``events ROBOT=BAG ...`` puts each robot's own bag on the team's time by the clock
    estimates it recorded, as team_clock's merge does, and prints what the merged log
    gives (the last line names the sidecar, which differs)."""
    with RobotBag(tmp_path / "b1", robot="blue1", ahead_s=2.5) as blue:
        for t in range(12):
            blue.add("fall/state", String(data="fallen" if 4 <= t < 6 else "standing"), t=t)
    with RobotBag(tmp_path / "r1", robot="red1", ahead_s=-1.3, drift_ppm=100) as red:
        for t in range(12):
            red.add("fall/state", String(data="fallen" if t >= 8 else "standing"), t=t)
    merged = subprocess.run(["ros2", "run", "team_clock", "team_clock", "merge", "-o",
                             str(tmp_path / "merged"), f"blue1={tmp_path / 'b1'}",
                             f"red1={tmp_path / 'r1'}"],
                            capture_output=True, text=True, timeout=60, check=False)
    assert merged.returncode == 0, merged.stderr
    from_merged = _events(tmp_path / "merged", "--only", "falls", cwd=tmp_path)
    from_bags = _events(f"blue1={tmp_path / 'b1'}", tmp_path / "r1", "--only", "falls",
                        cwd=tmp_path)
    assert from_bags.returncode == 0, from_bags.stderr
    assert from_bags.stdout.splitlines()[:-1] == from_merged.stdout.splitlines()[:-1]
    assert [line.split()[:6] for line in from_bags.stdout.splitlines()[1:4]] == [
        ["4.00", "s", "2.00", "s", "blue1", "fell"], ["6.00", "s", "0.00", "s", "blue1", "got"],
        ["8.00", "s", "3.00", "s", "red1", "fell"]]
    assert [e.name for e in read_events(tmp_path / "team.partial.events.mcap")] == [
        "fell", "got up", "fell"]  # --only: a partial run
    with LogBuilder(tmp_path / "plain") as plain:  # no clock estimates in it
        plain.add("", "fall/state", String(data="standing"), t=1.0)
    for args, status, says in (
            ((tmp_path / "b1", tmp_path / "plain"), 1, "on the team's time"),
            ((tmp_path / "b1", tmp_path / "r1", "--robot", "blue1"), 2, "give each as ROBOT=LOG")):
        run = _events(*args, cwd=tmp_path)
        assert run.returncode == status, (args, run.stderr)
        assert says in run.stderr, (args, run.stderr)
        assert "Traceback" not in run.stderr


def _cut_mid_chunk(log: Path, keep: float) -> tuple[Path, int]:
    """Cut the log's MCAP file in the middle of the chunk ``keep`` of the way through it,
    as a recorder killed while writing leaves it (no summary, a half-written chunk); the
    log time the cut chunk starts at."""
    (file,) = log.glob("*.mcap")
    with open(file, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 4
    chunk = chunks[int(len(chunks) * keep)]
    with open(file, "r+b") as f:
        f.truncate(chunk.chunk_start_offset + chunk.chunk_length // 2)
    return file, chunk.message_start_time


def test_a_log_cut_mid_chunk_is_analysed_up_to_the_cut_with_one_warning(
        tmp_path: Path) -> None:
    """A recorder killed mid-chunk: ``events`` and ``compare`` say where the file ends, in
    one line, and analyse everything before it."""
    with LogBuilder(tmp_path / "match") as log:
        for t in range(0, 60):
            for robot in ("blue1", "red1"):
                fallen = (t % 20) in (5, 6)
                log.add(robot, "fall/state", String(data="fallen" if fallen else "standing"),
                        t=t + (0.5 if robot == "red1" else 0.0))
            log.add("blue1", "behaviour/state", String(data="search" * 200), t=t)  # bulk
    file, cut_ns = _cut_mid_chunk(tmp_path / "match", keep=0.6)
    run = _events(tmp_path / "match", "--only", "falls", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr
    warnings = [line for line in run.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and f"{file}: readable up to byte" in warnings[0], run.stderr
    reason = warnings[0].rsplit(", then ", 1)[1]  # not an empty "EndOfFile: "
    assert re.fullmatch(r"\w+: \S.*", reason), warnings[0]
    found = read_events(tmp_path / "match.partial.events.mcap")
    # Every fall that began before the cut chunk is there, none after (a fall cut short
    # ends where the readable log does).
    before = [(e.robot, e.name, (e.start_ns - built_ns(0)) / 1e9) for e in found]
    expected = [(robot, name, float(t + (0.5 if robot == "red1" else 0.0) + (2 if name ==
                                                                            "got up" else 0)))
                for t in (5, 25, 45) for robot in ("blue1", "red1")
                for name in ("fell", "got up")]
    expected = [e for e in expected if built_ns(e[2]) < cut_ns - 10**9]
    assert len(expected) >= 4
    assert [e for e in before if built_ns(e[2]) < cut_ns - 10**9] == sorted(
        expected, key=lambda e: (e[2], e[0]))
    assert all(built_ns(e[2]) <= cut_ns for e in before), before

    frames = [(1.0 + k / 2, -10.0 + k / 3, False) for k in range(60)]
    images = seen_ball(tmp_path / "images", robot="blue1", frames=frames)
    file, image_cut_ns = _cut_mid_chunk(images, keep=0.5)
    run = subprocess.run(
        ["ros2", "run", "log_analysis", "compare", str(images), "--robot", "blue1", "--quiet",
         "--a", "colour=humanoid_sim::BallDetector", "--b", "blob=humanoid_sim::BlobBallDetector",
         "-o", str(tmp_path / "report")], cwd=tmp_path, capture_output=True, text=True,
        timeout=90, check=False)
    assert run.returncode == 0, run.stderr
    (warning,) = run.stderr.splitlines()
    assert warning.startswith(f"compare: warning: {file}: readable up to byte"), run.stderr
    replayed = re.search(r": (\d+) images", run.stdout)
    assert replayed, run.stdout
    # The images before the cut chunk, all of them replayed.
    assert sum(1 for t, _, _ in frames if t * 1e9 < image_cut_ns) <= int(replayed[1]) \
        < len(frames), run.stdout


def built_ns(t: float) -> int:
    """The log time of ``t`` seconds in a LogBuilder log (epoch 1000 s)."""
    return round((1000.0 + t) * 1e9)


def test_a_video_without_frames_is_one_line_and_anchors_still_fit(tmp_path: Path) -> None:
    """A video whose writer never got a frame (a camera that failed at once): the commands
    that read its frames say so in one line; a fit by hand, which needs no frames, works."""
    log, video = film_ball(tmp_path, _kicked, seconds=8, offset_s=0.5, drift_ppm=0)
    empty = tmp_path / "empty.mp4"
    with av.open(str(empty), "w") as container:
        stream: Any = container.add_stream("libx264", rate=5)
        stream.width, stream.height, stream.pix_fmt = 480, 270, "yuv420p"
        container.start_encoding()  # the header, then nothing
    Path(f"{empty}.json").write_text(Path(f"{video}.json").read_text())
    anchored = _sync(log, empty, "--anchor", "1.0=0.5", "-o", tmp_path / "hand.json",
                     cwd=tmp_path)
    assert anchored.returncode == 0, anchored.stderr
    # camera 0.5 s + 1.0 s = log 0.5 s: the camera 1 s ahead
    assert json.loads((tmp_path / "hand.json").read_text())["offset_ns"] == 1_000_000_000
    for command in ("sync-video", "augment"):
        run = subprocess.run(["ros2", "run", "log_analysis", command, str(log), str(empty),
                              *(["--fit", str(tmp_path / "hand.json")] if command == "augment"
                                else [])],
                             cwd=tmp_path, capture_output=True, text=True, timeout=90,
                             check=False)
        assert run.returncode == 1, (command, run.stderr)
        assert "Traceback" not in run.stderr
        lines = [line for line in run.stderr.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith(f"{command}: error: "), run.stderr
        assert lines[0].startswith(f"{command}: error: {empty} has no frames"), run.stderr
    assert list(tmp_path.glob("*empty.augmented*")) == []  # nothing half-written left


def test_a_log_and_a_video_of_different_matches_are_refused_not_fitted(
        tmp_path: Path) -> None:
    """The newcomer's case: sync-video given one match's log and another's video found a
    'best' offset on 2 frames at 12 px and said nothing; augment then reused a fit made on
    another log. Both are one line and exit 1, saying what would help."""
    log_a, video_a = film_ball(tmp_path / "a", _kicked, seconds=30, offset_s=-2.35,
                               drift_ppm=0)
    log_b, video_b = film_ball(tmp_path / "b", lambda t: (1.5 - 0.1 * (t % 20), -1.0),
                               seconds=12, offset_s=5.0, drift_ppm=0)
    for log, video in ((log_a, video_b), (log_b, video_a)):
        run = _sync(log, video, "--quiet", cwd=tmp_path)
        assert run.returncode == 1, run.stdout
        lines = run.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("sync-video: error: "), run.stderr
        assert "same match" in lines[0] and "--anchor" in lines[0], run.stderr
        assert not Path(f"{video}.sync.json").exists()
    # A fit on the right log records which log it was; augment refuses it for another.
    run = _sync(log_a, video_a, "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    fit = json.loads(Path(f"{video_a}.sync.json").read_text())
    assert fit["log_path"] == str(log_a.resolve()) and fit["log_end_ns"] > 0
    run = _augment(log_b, video_a, "--quiet", "-o", tmp_path / "x.mp4", cwd=tmp_path)
    assert run.returncode == 1
    assert run.stderr.strip().splitlines() == [
        f"augment: error: the fit was made on another log ({log_a.resolve()}), not on "
        f"{log_b}: run sync-video on this log and video again"], run.stderr
    assert not (tmp_path / "x.mp4").exists()


def test_drift_only_when_the_data_supports_it_and_an_implausible_one_refused(
        tmp_path: Path) -> None:
    """Two 20 s stretches cannot pin a drift (the newcomer got +1250 ppm for a true -14):
    the fit is then the offset alone and says so; two anchors giving 62500 ppm are refused
    unless --allow-drift."""
    log, video = film_ball(tmp_path, _kicked, seconds=30, offset_s=-2.35, drift_ppm=0)
    run = _sync(log, video, "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "drift 0 (not fitted" in run.stdout
    fit = json.loads(Path(f"{video}.sync.json").read_text())
    assert fit["drift_ppm"] == 0 and fit["drift_fitted"] is False
    hand = ("--anchor", "0=0", "--anchor", "8=7.5", "-o", tmp_path / "hand.json")
    run = _sync(log, video, *hand, cwd=tmp_path)
    assert run.returncode == 1
    assert "a drift of +62500 ppm is implausible" in run.stderr and "--allow-drift" \
        in run.stderr, run.stderr
    run = _sync(log, video, *hand, "--allow-drift", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert re.search(r"drift \+62500\.0 ± \d+\.\d ppm", run.stdout), run.stdout


def test_robot_is_that_robots_part_and_partial_runs_leave_the_full_sidecar(
        tmp_path: Path) -> None:
    """``--robot NAME`` is NAME's part of the log (the newcomer's merged log and the demo's
    /robot/... bag gave 0 messages); a run over no topic is an error naming the log's
    robots; a partial run writes ``LOG.partial.events.mcap`` and leaves the full sidecar."""
    _log(tmp_path / "match")
    full = _events("match", "--quiet", cwd=tmp_path)
    assert full.returncode == 0, full.stderr
    sidecar = tmp_path / "match.events.mcap"
    before = sidecar.read_bytes()
    run = _events("match", "--robot", "red1", "--only", "falls", "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "1 events from 1 generators over 2 messages" in run.stdout, run.stdout
    assert "(partial: --only --robot; match.events.mcap is left as it was)" in run.stdout
    assert [(e.robot, e.name) for e in read_events(tmp_path / "match.partial.events.mcap")] \
        == [("red1", "fell")]
    assert sidecar.read_bytes() == before
    run = _events("match", "--start", "5", "--quiet", cwd=tmp_path)
    assert "written to match.partial.events.mcap (partial: --start" in run.stdout
    assert sidecar.read_bytes() == before
    for args, says in (
            (("--robot", "red9"), "for robot red9: the log's robots are blue1, red1"),
            (("--only", "goals"), "no topic of match is one the generators read "
                                  "(/world/game_state) for any robot")):
        run = _events("match", *args, "--quiet", cwd=tmp_path)
        assert run.returncode == 1, (args, run.stdout)
        lines = run.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("events: error: "), run.stderr
        assert says in run.stderr, (args, run.stderr)
    typo = tmp_path / "typo.py"
    typo.write_text(KICKS.replace('"behaviour/state"', '"behaviour/stat"'))
    run = _events("match", "--generators", typo, "--quiet", "-o", tmp_path / "t.mcap",
                  cwd=tmp_path)
    assert "events: warning: kicks reads behaviour/stat, which no robot logged (the log's " \
        "robots: blue1, red1): it finds nothing" in run.stderr, run.stderr


def test_an_events_sidecar_given_as_the_log_is_refused(tmp_path: Path) -> None:
    """``events match/`` one level too high read the sidecar beside the log as the log."""
    _log(tmp_path / "match" / "merged")
    assert _events("match/merged", "--quiet", cwd=tmp_path).returncode == 0
    for log, says in (("match", "match holds only events sidecars (merged.events.mcap), no "
                                "log: give the log's own folder"),
                      ("match/merged.events.mcap", "match/merged.events.mcap is an events "
                       "sidecar (what events writes), not a log")):
        run = _events(log, "--quiet", cwd=tmp_path)
        assert run.returncode == 1, run.stdout
        assert run.stderr.startswith(f"events: error: {says}"), run.stderr
        assert len(run.stderr.strip().splitlines()) == 1
    # The log's own .mcap file: the sidecar goes beside the bag folder, not into it.
    (file,) = (tmp_path / "match" / "merged").glob("*.mcap")
    run = _events(file, "--quiet", "--only", "falls", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "match" / "merged.partial.events.mcap").exists()
    assert list((tmp_path / "match" / "merged").glob("*events*")) == []


FINISH_NONE = """
class Slow:
    topics = ["fall/state"]
    name = "slow"

    def __call__(self, m):
        return []

    def finish(self, end_ns):
        pass


GENERATORS = [Slow()]
"""


def test_bad_options_and_generator_files_are_one_line_not_a_traceback(tmp_path: Path
                                                                       ) -> None:
    """The newcomer's tracebacks and silent surprises: -o to a missing directory or to a
    directory, --start nan, a window past the log's end, a generators file given twice or
    naming a built-in, --only ignoring files, a finish() returning None."""
    _log(tmp_path / "match")
    for args, status, says in (
            (("-o", tmp_path / "no" / "x.mcap"), 1,
             f"events: error: -o {tmp_path / 'no' / 'x.mcap'}: no directory"),
            (("-o", tmp_path), 1, f"events: error: -o {tmp_path} is a directory"),
            (("--start", "nan"), 2, "not a number of seconds: 'nan'")):
        run = _events("match", "--quiet", *args, cwd=tmp_path)
        assert run.returncode == status, (args, run.stdout)
        assert says in run.stderr and "Traceback" not in run.stderr, (args, run.stderr)
    assert not list(tmp_path.glob("*.partial"))
    run = _events("match", "--quiet", "--start", "100", cwd=tmp_path)
    assert "events: warning: the window 100..end s holds none of the log: the log spans " \
        "0..10.0 s" in run.stderr, run.stderr
    mine = tmp_path / "mine.py"
    mine.write_text(KICKS.replace("GENERATORS = [kicks, grumpy]", "GENERATORS = [kicks]"))
    run = _events("match", "--quiet", "--generators", mine, "--generators", f"./{mine.name}",
                  "-o", tmp_path / "twice.mcap", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert [e.name for e in read_events(tmp_path / "twice.mcap")].count("kick") == 2
    run = _events("match", "--quiet", "--generators", mine, "--only", "falls", "-o",
                  tmp_path / "only.mcap", cwd=tmp_path)
    assert "kick" not in [e.name for e in read_events(tmp_path / "only.mcap")]
    other = tmp_path / "other.py"
    other.write_text(mine.read_text())
    run = _events("match", "--quiet", "--generators", mine, "--generators", other,
                  cwd=tmp_path)
    assert run.returncode == 1
    assert run.stderr.strip() == (f"events: error: two generators are named 'kicks': in "
                                  f"{mine} and in {other}; rename one"), run.stderr
    mine.write_text(KICKS.replace("def kicks", "def falls").replace("[kicks, grumpy]",
                                                                      "[falls]"))
    run = _events("match", "--quiet", "--generators", mine, "--only", "falls", "-o",
                  tmp_path / "own.mcap", cwd=tmp_path)  # the user's falls, not the built-in
    assert run.returncode == 0, run.stderr
    assert [e.name for e in read_events(tmp_path / "own.mcap")] == ["kick", "kick"]
    slow = tmp_path / "slow.py"
    slow.write_text(FINISH_NONE)
    run = _events("match", "--quiet", "--generators", slow, "--only", "slow", "-o",
                  tmp_path / "slow.mcap", cwd=tmp_path)
    assert run.returncode == 1
    assert run.stderr.strip() == ("events: error: generator slow failed and was left out: "
                                  f"returned None, not a list of events (at {slow}:9)"), \
        run.stderr


def test_ball_topic_must_be_a_field_frame_position(tmp_path: Path) -> None:
    """``--ball-topic`` for a robot's belief: its ``ball/position`` is in base_footprint
    (taken as field coordinates it fitted the newcomer's video 9 s off), its ``role`` no
    position (a traceback); both refused in one line; a field-frame
    PoseWithCovarianceStamped (``team_ball``, once an AttributeError) is fitted."""
    log, video = film_ball(tmp_path, _kicked, seconds=30, offset_s=-2.35, drift_ppm=0,
                           robots={"blue1": lambda t: (-2.0, 0.0, 0.3)})
    for topic, says in (
            ("/blue1/ball/position", "/blue1/ball/position is in the frame "
                                     "'base_footprint', not the field's"),
            ("/blue1/role", "/blue1/role is a std_msgs/msg/String, not a ball position")):
        run = _sync(log, video, "--ball-topic", topic, "--quiet", cwd=tmp_path)
        assert run.returncode == 1, run.stdout
        lines = run.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"sync-video: error: {says}"), \
            run.stderr
    run = _sync(log, video, "--ball-topic", "/blue1/team_ball", "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    fit = json.loads(Path(f"{video}.sync.json").read_text())
    assert abs(fit["offset_ns"] + 2.35e9) < 100e6, fit  # half a frame at 5 fps


def test_each_commands_help_is_its_own_and_wrong_arguments_exit_2(tmp_path: Path) -> None:
    """Every subcommand's --help began with the whole module's help (and compare's example
    lost its line breaks); --only nosuch exited 1 though wrong arguments exit 2; -o x.avi
    wrote MP4 bytes into an .avi; VideoFit was not importable from log_analysis."""
    helps = {command: subprocess.run(["ros2", "run", "log_analysis", command, "--help"],
                                     capture_output=True, text=True, timeout=60,
                                     check=True).stdout
             for command in ("events", "sync-video", "augment", "compare")}
    for command, text in helps.items():
        others = [c for c in helps if c != command]
        assert f"``{command}``: " in text
        assert not any(f"``{other}``: " in text for other in others), (command, text)
        assert "--quiet`` turns it off" in text  # the paragraph they share
    assert "compare LOG --robot blue1 \\\n" in helps["compare"]
    assert "(default: 2)" in helps["compare"] and "(default: 30)" in helps["sync-video"]
    _log(tmp_path / "match")
    run = _events("match", "--only", "nosuch", cwd=tmp_path)
    assert run.returncode == 2 and "unknown event generator(s) nosuch; known: " in run.stderr
    run = _augment("match", "video.mp4", "-o", "x.avi", cwd=tmp_path)
    assert run.returncode == 2, run.stderr
    assert "augment: error: augment writes an MP4 (H.264): -o must end in .mp4, not x.avi" \
        in run.stderr
    assert not (tmp_path / "x.avi").exists()
    from log_analysis import VideoFit, check_fit  # noqa: F401  (exported)
    listed = _events("--list", cwd=tmp_path).stdout.splitlines()
    assert listed and all(line.endswith(".") for line in listed), listed  # whole sentences
