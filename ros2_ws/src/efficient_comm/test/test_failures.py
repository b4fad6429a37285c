"""A callback that keeps raising: its first traceback in full, then summaries with counts."""

from __future__ import annotations

from std_msgs.msg import String

from efficient_comm._failures import SUMMARY_INTERVAL_NS
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import TestHandle


class Broken:
    """Raises on every message and on every tick (a sensor unplugged, say)."""

    def __init__(self, node: NodeHandle) -> None:
        node.create_subscription(String, "in", self.on_in)
        node.create_timer(0.01, self.tick)

    def on_in(self, msg: String) -> None:
        raise RuntimeError(f"cannot parse {msg.data}")

    def tick(self) -> None:
        raise OSError("device gone")


def _errors(node: TestHandle) -> list[str]:
    return [message for level, message in node.records if level == "error"]


def test_a_callback_raising_on_every_call_logs_one_traceback_then_summaries() -> None:
    node = TestHandle("broken")
    Broken(node)
    for i in range(50):
        node.inject("in", String(data=str(i)))
    errors = _errors(node)
    assert len(errors) == 1 and "Traceback" in errors[0] and "cannot parse 0" in errors[0]
    assert "/in" in errors[0]

    node.advance(SUMMARY_INTERVAL_NS / 1e9 + 0.01)  # the timer fails 1,001 times meanwhile
    node.inject("in", String(data="last"))
    errors = _errors(node)
    timer = [e for e in errors if "device gone" in e]
    on_in = [e for e in errors[1:] if "cannot parse" in e]
    assert len(timer) == 2 and "Traceback" in timer[0]  # first in full, one summary
    assert "Traceback" not in timer[1] and "in all" in timer[1]
    assert len(on_in) == 1 and "Traceback" not in on_in[0]
    # 50 + 1 calls: the summary counts the 49 repeats since the first and the one now.
    assert "cannot parse last (and 49 more" in on_in[0] and "51 in all" in on_in[0]
    stats = {s.kind: s for s in node.container.stats() if s.node == "/broken"}
    assert stats["subscription"].exceptions == 51 and stats["timer"].exceptions == 1001


def test_another_kind_of_failure_gets_its_own_traceback() -> None:
    node = TestHandle("moody")
    fail = [ValueError("first"), KeyError("second"), ValueError("first")]

    def on_in(_msg: String) -> None:
        raise fail.pop(0)

    node.create_subscription(String, "in", on_in)
    node.inject("in", String(), String(), String())
    errors = _errors(node)
    assert len(errors) == 2 and all("Traceback" in e for e in errors)
    assert "ValueError: first" in errors[0] and "KeyError: 'second'" in errors[1]
