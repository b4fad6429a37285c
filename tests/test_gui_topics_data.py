"""The topics view's rates against a light robot (no browser): a rate the GUI measured at
its own echo rate is not passed off as the topic's."""

from __future__ import annotations

from pathlib import Path

from debug_gui import Hub, RobotId
from debug_gui.models.topics import ECHO_HZ, TopicsModel
from efficient_comm.testing import isolated_domain_id

from ._gui import fake_robot, wait_for


def test_a_rate_capped_by_the_echo_says_so(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    robot = RobotId(domain, "/capped")
    with fake_robot(tmp_path, domain_id=domain, namespace="/capped") as proc, \
            Hub(domains=[domain]) as hub:
        wait_for(lambda: robot in hub.robots(), what="the robot", alive=[proc])
        model = TopicsModel(hub, robot)
        model.activate()
        try:
            model.echo("chatter", "std_msgs/msg/String")  # 20 Hz, echoed at 5 Hz

            def chatter() -> dict[str, object] | None:
                row = next(t for t in model.topics() if t["name"] == "/capped/chatter")
                return row if row["rate_capped"] else None

            # Awaited: the first rates measured on a loaded machine may fall short of the
            # cap (then they are the topic's rate as far as anyone here can tell).
            row = wait_for(chatter, what="chatter's rate said to be capped", alive=[proc])
            assert row["rate_source"] == "received"
            assert isinstance(row["rate_hz"], float) and row["rate_hz"] <= ECHO_HZ * 1.2
        finally:
            model.deactivate()
