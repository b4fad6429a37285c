"""The ros2 command (ros2_pip_cli): how soon it answers, and whether echo and hz keep up.

1. Graph answers: with three plain rclpy peer processes running (each a node with a topic),
   the wall time of ``ros2 topic list`` and ``ros2 node list --no-daemon`` against a plain
   rclpy script that knows what to expect and exits as soon as it has seen it (the best any
   discovery can do, Python start-up included). Ratio = command / baseline.
   Then the graph daemon: ``topic list``, ``node list``, ``service list``, ``topic info T``
   and ``topic info`` of a topic nobody has, each timed cold (no daemon running: the call
   starts one), warm (the next call) and with ``--no-daemon``; ratios against
   ``--no-daemon`` in the same run. Warm answers are compared with ``--no-daemon`` ones.
2. Keeping up: a publisher process sends std_msgs/String at 1 kHz, or 1 MiB
   sensor_msgs/Image at 30 Hz, numbering each message; ``ros2 topic hz`` reports a rate
   (ratio to the rate sent) and ``ros2 topic echo`` prints messages (ratio of the numbers
   printed to those sent while it listened).

Run: ``source scripts/env.sh && python bench/cli_bench.py [--repeat 3]``. Medians printed
as a Markdown table; every run's values in bench/out/cli_bench.json.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from efficient_comm.testing import isolated_domain_id, stop_process_group  # noqa: E402
from ros2_pip_cli import DAEMON_DIR_ENV, stop_daemons  # noqa: E402
from tests._cli import cli_env, ros2_path  # noqa: E402

LISTEN_S = 6.0
PEERS = 3
MIB = 1 << 20

PEER_CODE = """
import sys, rclpy
from rclpy.node import Node
from std_msgs.msg import String
rclpy.init()
node = Node(sys.argv[1])
node.create_publisher(String, sys.argv[2], 10)
print("ready", flush=True)
try:
    rclpy.spin(node)
except KeyboardInterrupt:
    pass
"""

BASELINE_CODE = """
import sys, rclpy
from rclpy.node import Node
want_nodes, want_topics = set(sys.argv[1].split(",")), set(sys.argv[2].split(","))
rclpy.init()
node = Node("_baseline")
while True:
    rclpy.spin_once(node, timeout_sec=0.01)
    nodes = {"/" + n for n, _ in node.get_node_names_and_namespaces()}
    topics = {t for t, _ in node.get_topic_names_and_types()}
    if want_nodes <= nodes and want_topics <= topics:
        break
print("\\n".join(sorted(topics)))
"""

PUBLISHER_CODE = """
import sys, time, rclpy
from rclpy.node import Node
kind, topic, rate, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
rclpy.init()
node = Node("bench_publisher")
if kind == "string":
    from std_msgs.msg import String
    pub = node.create_publisher(String, topic, 10)
    make = lambda n: String(data=str(n))
else:
    from sensor_msgs.msg import Image
    pub = node.create_publisher(Image, topic, 10)
    img = Image(height=512, width=512, encoding="rgba8", step=2048)
    img.data = bytes(1 << 20)
    def make(n):
        img.header.frame_id = str(n)
        return img
while pub.get_subscription_count() == 0:
    rclpy.spin_once(node, timeout_sec=0.01)
print("matched", flush=True)
period, start, n = 1.0 / rate, time.monotonic(), 0
while time.monotonic() - start < seconds:
    due = start + n * period
    now = time.monotonic()
    if now < due:
        time.sleep(due - now)
    n += 1
    pub.publish(make(n))
elapsed = time.monotonic() - start
print(f"sent {n} {elapsed:.6f}", flush=True)
"""


def _python(code: str, *args: str, env: dict[str, str], **kw: Any) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", code, *args], env=env, text=True,
                            start_new_session=True, **kw)



def graph_answers(env: dict[str, str], cases: list[str]) -> dict[str, float]:
    peers = []
    names = [f"peer{i}" for i in range(PEERS)]
    topics = [f"/bench_topic{i}" for i in range(PEERS)]
    try:
        for name, topic in zip(names, topics, strict=True):
            p = _python(PEER_CODE, name, topic, env=env, stdout=subprocess.PIPE)
            peers.append(p)
            assert p.stdout is not None and p.stdout.readline().strip() == "ready"
        time.sleep(1.0)  # the peers have found each other: a steady system is the case measured
        out: dict[str, float] = {}
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", BASELINE_CODE, ",".join("/" + n for n in names),
                        ",".join(topics)], env=env, check=True, capture_output=True, timeout=60)
        out["baseline_s"] = time.perf_counter() - t0
        for verb in ("topic", "node"):
            t0 = time.perf_counter()
            result = subprocess.run([ros2_path(), verb, "list", "--no-daemon"], env=env,
                                    capture_output=True, text=True, timeout=60)
            out[f"{verb}_list_s"] = time.perf_counter() - t0
            expected = topics if verb == "topic" else ["/" + n for n in names]
            out[f"{verb}_list_complete"] = float(
                set(expected) <= set(result.stdout.split()))
        out.update(daemon_answers(env, topics[0], cases))
        return out
    finally:
        for p in peers:
            stop_process_group(p)


#: What the daemon part times: a label and the command's arguments.
DAEMON_CASES = {
    "topic_list": ["topic", "list"],
    "node_list": ["node", "list"],
    "service_list": ["service", "list"],
    "topic_info": ["topic", "info", "{topic}"],
    "unknown_topic": ["topic", "info", "/bench_nobody_has_this"],
}


def _timed(args: list[str], env: dict[str, str]) -> tuple[float, str]:
    t0 = time.perf_counter()
    result = subprocess.run([ros2_path(), *args], env=env, capture_output=True, text=True,
                            timeout=60)
    return time.perf_counter() - t0, f"{result.returncode}\n{result.stdout}{result.stderr}"


def daemon_answers(env: dict[str, str], topic: str, cases: list[str]) -> dict[str, float]:
    """Cold, warm and --no-daemon wall times per case (and whether warm == --no-daemon)."""
    out: dict[str, float] = {}
    stop = [ros2_path(), "daemon", "stop"]
    for case in cases:
        template = DAEMON_CASES[case]
        args = [a.format(topic=topic) for a in template]
        subprocess.run(stop, env=env, capture_output=True, timeout=60, check=True)
        out[f"{case}_cold_s"], _ = _timed(args, env)
        out[f"{case}_warm_s"], warm = _timed(args, env)
        out[f"{case}_no_daemon_s"], direct = _timed([*args, "--no-daemon"], env)
        out[f"{case}_same"] = float(warm == direct)
    subprocess.run(stop, env=env, capture_output=True, timeout=60, check=True)
    return out


def keeping_up(env: dict[str, str], kind: str, rate: float, tmp: Path,
               listen_s: float = LISTEN_S) -> dict[str, float]:
    topic = f"/bench_{kind}"
    out: dict[str, float] = {}
    for verb in ("hz", "echo"):
        log = tmp / f"{kind}_{verb}.log"
        with open(log, "w") as stream:
            args = [ros2_path(), "topic", verb, topic]
            if verb == "echo" and kind == "image":
                args += ["--no-arr"]
            cli = subprocess.Popen(args, env=env, stdout=stream, stderr=subprocess.STDOUT,
                                   text=True, start_new_session=True)
            pub = _python(PUBLISHER_CODE, kind, topic, str(rate), str(listen_s), env=env,
                          stdout=subprocess.PIPE)
            try:
                text, _ = pub.communicate(timeout=listen_s + 60)
            finally:
                stop_process_group(pub)
                time.sleep(0.5)
                stop_process_group(cli)
        match = re.search(r"sent (\d+) ([\d.]+)", text)
        assert match, text
        sent, elapsed = int(match.group(1)), float(match.group(2))
        sent_rate = sent / elapsed
        output = log.read_text(errors="replace")
        if verb == "hz":
            rates = [float(r) for r in re.findall(r"average rate: ([\d.]+)", output)]
            assert rates, output
            out["hz_seen"], out["hz_sent"] = rates[-1], sent_rate
        else:
            field = "data" if kind == "string" else "frame_id"
            numbers = [int(n) for n in re.findall(rf"{field}: '?(\d+)'?\n", output)]
            assert numbers, output[:2000]
            window = max(numbers) - min(numbers) + 1
            out["echo_printed"] = len(set(numbers))
            out["echo_ratio"] = len(set(numbers)) / window
            out["echo_window"] = window
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", default=str(ROOT / "bench" / "out" / "cli_bench.json"))
    parser.add_argument("--listen", type=float, default=LISTEN_S,
                        help=f"seconds each rate measurement publishes (default: {LISTEN_S})")
    parser.add_argument("--cases", default=",".join(DAEMON_CASES),
                        help="the graph daemon's cases to time, comma-separated (default: "
                        "all of them: " + ", ".join(DAEMON_CASES) + ")")
    args = parser.parse_args()
    args.cases = [c for c in args.cases.split(",") if c]
    unknown = sorted(set(args.cases) - set(DAEMON_CASES))
    if unknown or not args.cases:
        parser.error(f"--cases: {', '.join(unknown) or 'none given'}: choose from "
                     + ", ".join(DAEMON_CASES))
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp, tempfile.TemporaryDirectory() as daemons:
        try:
            runs = _runs(args, Path(tmp), Path(daemons))
        finally:
            stop_daemons(directory=Path(daemons))
    _report(runs, args.out)
    return 0


def _runs(args: argparse.Namespace, tmp: Path, daemons: Path) -> list[dict[str, Any]]:
    runs: list[dict[str, Any]] = []
    for i in range(args.repeat):
        env = cli_env(isolated_domain_id())
        env[DAEMON_DIR_ENV] = str(daemons)
        run: dict[str, Any] = {"graph": graph_answers(env, args.cases)}
        run["string_1khz"] = keeping_up(env, "string", 1000.0, tmp, args.listen)
        run["image_30hz_1mib"] = keeping_up(env, "image", 30.0, tmp, args.listen)
        runs.append(run)
        print(f"run {i + 1}: {json.dumps(run)}", file=sys.stderr, flush=True)
    return runs


def _report(runs: list[dict[str, Any]], out: str) -> None:

    def med(section: str, key: str) -> float:
        return float(statistics.median(r[section][key] for r in runs))

    base = med("graph", "baseline_s")
    print(f"| measure (median of {len(runs)}) | value | ratio |")
    print("|---|---|---|")
    print(f"| plain rclpy script waiting for the known graph | {base:.2f} s | 1.00 |")
    for verb in ("topic", "node"):
        value = med("graph", f"{verb}_list_s")
        complete = sum(r["graph"][f"{verb}_list_complete"] for r in runs)
        print(f"| `ros2 {verb} list --no-daemon` ({complete:.0f}/{len(runs)} complete) | "
              f"{value:.2f} s | "
              f"{value / base:.2f} |")
    for section, label in (("string_1khz", "String 1 kHz"),
                           ("image_30hz_1mib", "Image 1 MiB 30 Hz")):
        seen, sent = med(section, "hz_seen"), med(section, "hz_sent")
        print(f"| `ros2 topic hz`, {label}: rate seen / sent | {seen:.1f} / {sent:.1f} Hz | "
              f"{seen / sent:.3f} |")
        print(f"| `ros2 topic echo`, {label}: messages printed / sent while listening | "
              f"{med(section, 'echo_printed'):.0f} / {med(section, 'echo_window'):.0f} | "
              f"{med(section, 'echo_ratio'):.3f} |")
    print()
    print(f"| graph daemon (median of {len(runs)}) | cold | warm | --no-daemon | "
          "warm / --no-daemon | cold / --no-daemon | warm == --no-daemon |")
    print("|---|---|---|---|---|---|---|")
    for case, template in DAEMON_CASES.items():
        if f"{case}_same" not in runs[0]["graph"]:
            continue  # not timed (--cases)
        cold, warm, direct = (med("graph", f"{case}_{k}_s")
                              for k in ("cold", "warm", "no_daemon"))
        same = sum(r["graph"][f"{case}_same"] for r in runs)
        shown = " ".join(template).replace("{topic}", "T")
        print(f"| `ros2 {shown}` | {cold:.2f} s | {warm:.2f} s | {direct:.2f} s | "
              f"{warm / direct:.3f} | {cold / direct:.2f} | {same:.0f}/{len(runs)} |")
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    sys.exit(main())
