"""``ros2 component`` against an efficient_comm container, ``ros2 bag`` against a plain rclpy
publisher: record, info (rosbag2's summary), play with remapping and reindex."""

from __future__ import annotations

import re
import signal
import sys
from pathlib import Path

import yaml

from efficient_comm.testing import isolated_domain_id, unique_topic

from ._cli import ROOT, ros2, ros2_path, running

PEER = ROOT / "tests" / "_cli_peer.py"


def test_component_load_list_unload(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    with running([ros2_path(), "run", "efficient_comm", "container", "--name", "robot"],
                 domain_id=domain_id, log=tmp_path / "container.log"):
        loaded = ros2("component", "load", "/robot", "efficient_comm",
                      "efficient_comm.examples.pipeline:Camera", "-n", "cam",
                      "-p", "rate_hz:=5.0", domain_id=domain_id)
        assert loaded.returncode == 0, loaded.stderr
        match = re.fullmatch(r"Loaded component (\d+) into '/robot' container node as '/cam'\n",
                             loaded.stdout)
        assert match, loaded.stdout
        uid = match.group(1)
        listed = ros2("component", "list", domain_id=domain_id)
        assert f"/robot\n  {uid}  /cam\n" in listed.stdout, listed
        assert ros2("component", "list", "/robot", domain_id=domain_id).stdout == f"{uid}  /cam\n"
        bad = ros2("component", "load", "/robot", "x", "no.such:Class", domain_id=domain_id)
        assert bad.returncode == 1 and "Failed to load component" in bad.stderr
        assert len(bad.stderr.strip().splitlines()) == 1, bad.stderr
        unloaded = ros2("component", "unload", "/robot", uid, domain_id=domain_id)
        assert unloaded.stdout == f"Unloaded component {uid} from '/robot' container node\n"
        assert ros2("component", "list", "/robot", domain_id=domain_id).stdout == ""


def test_bag_record_info_play_reindex(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    topic = unique_topic("bag")
    with running([sys.executable, str(PEER), topic], domain_id=domain_id,
                 log=tmp_path / "peer.log") as peer:
        peer.wait_for(lambda t: "ready" in t)
        with running([ros2_path(), "bag", "record", "-o", "out", "--topics", topic],
                     domain_id=domain_id, log=tmp_path / "record.log", cwd=tmp_path) as rec:
            rec.wait_for(lambda t: "Recording to 'out'" in t)
            bag = tmp_path / "out"
            rec.wait_for(lambda t: any(p.stat().st_size > 2000 for p in bag.glob("*.mcap")),
                         timeout=60)
            assert rec.stop(signal.SIGINT) == 0, rec.text()
    info = ros2("bag", "info", str(bag), domain_id=domain_id)
    assert info.returncode == 0, info.stderr
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    count = meta["message_count"]
    assert count > 0
    assert re.search(r"\nFiles:             out_0\.mcap\nBag size:          \d+\.\d KiB\n"
                     r"Storage id:        mcap\nROS Distro:        jazzy\n"
                     r"Duration:          \d+\.\d{9}s\nStart:             \w{3} [ \d]\d \d{4} "
                     r"\d\d:\d\d:\d\d\.\d{9} \(\d+\.\d{9}\)\n", info.stdout), info.stdout
    assert (f"Messages:          {count}\nTopic information: Topic: {topic} | Type: "
            f"std_msgs/msg/String | Count: {count} | Serialization Format: cdr\n"
            in info.stdout), info.stdout
    (bag / "metadata.yaml").unlink()
    reindexed = ros2("bag", "reindex", str(bag), domain_id=domain_id)
    assert reindexed.stdout == f"Reindexed '{bag}': {count} messages\n", reindexed.stderr
    assert f"Count: {count} |" in ros2("bag", "info", str(bag), domain_id=domain_id).stdout
    replay = unique_topic("replay")
    # --loop: a bag shorter than the new player's discovery of the echo still reaches it
    # (one play could be over before they have matched).
    with running([ros2_path(), "topic", "echo", replay, "std_msgs/msg/String"],
                 domain_id=domain_id, log=tmp_path / "echo.log") as echo, \
         running([ros2_path(), "bag", "play", str(bag), "--loop", "--remap",
                  f"{topic}:={replay}"], domain_id=domain_id, log=tmp_path / "play.log") as play:
        echo.wait_for(lambda t: re.search(r"data: hello \d+\n---\n", t) is not None)
        assert play.stop(signal.SIGINT) == 0, play.text()


def test_bag_record_split_compression_and_play_options(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    topic = unique_topic("split")
    with running([sys.executable, str(PEER), topic], domain_id=domain_id,
                 log=tmp_path / "peer.log") as peer:
        peer.wait_for(lambda t: "ready" in t)
        with running([ros2_path(), "bag", "record", topic, "-o", "split", "-s", "mcap",
                      "--max-bag-size", "3000", "--compression-mode", "file",
                      "--compression-format", "lz4"],
                     domain_id=domain_id, log=tmp_path / "record.log", cwd=tmp_path) as rec:
            bag = tmp_path / "split"
            rec.wait_for(lambda t: len(list(bag.glob("*.mcap"))) >= 3, timeout=60)
            assert rec.stop(signal.SIGINT) == 0, rec.text()
    info = ros2("bag", "info", str(bag), domain_id=domain_id).stdout
    assert re.search(r"Files:             split_0\.mcap\n {19}split_1\.mcap\n", info), info
    assert ros2("bag", "record", "-s", "sqlite3", "-a", domain_id=domain_id).returncode == 2
    played = unique_topic("played")
    with running([ros2_path(), "topic", "echo", played, "std_msgs/msg/String"],
                 domain_id=domain_id, log=tmp_path / "echo.log") as echo, \
         running([ros2_path(), "bag", "play", str(bag), "--topics", topic, "--remap",
                  f"{topic}:={played}", "--rate", "4", "--start-offset", "0.5", "--loop"],
                 domain_id=domain_id, log=tmp_path / "play.log") as play:
        echo.wait_for(lambda t: "data: hello" in t)
        assert play.stop(signal.SIGINT) == 0, play.text()
