"""A debug_gui server whose source is recorded, not live: the views' "not live" states.

``python tests/_gui_recorded_server.py`` serves, on a free port, the recorder, parameters
and image views of one robot ``/rec1`` (domain 0) over a ``debug_gui.testing.FakeSource``
with ``live=False`` (what a log's playback is to the views: no service answers), fed
every 0.2 s with a recorder status and a parameter event as a log would replay them.
Prints ``debug_gui: serving ... at URL`` (with the writer's token) as the command does.
"""

from __future__ import annotations

import os
import sys
import threading

from debug_gui import AccessPolicy, RobotId
from debug_gui.layout import Layout, Panel
from debug_gui.server import free_port, url
from debug_gui.testing import FakeSource

ROBOT = RobotId(0, "/rec1")


def main() -> int:
    os.environ.pop("PYTEST_CURRENT_TEST", None)  # see debug_gui.server.serve
    from nicegui import app, ui
    from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterType, ParameterValue

    from debug_gui.ui import registry
    from debug_gui.ui.app import Shell, install
    from robot_recorder_interfaces.msg import RecorderStatus

    source = FakeSource(live=False)
    source.add_robot(ROBOT, topics={
        "recorder/status": "robot_recorder_interfaces/msg/RecorderStatus",
        "camera/image_raw/compressed": "sensor_msgs/msg/CompressedImage",
    })
    stop = threading.Event()

    def replay() -> None:
        """What a playback delivers: the recorder's status, a parameter's changes."""
        tick = 0
        while not stop.wait(0.2):
            tick += 1
            source.advance(0.2)
            source.publish(ROBOT, "recorder/status", RecorderStatus(
                state=RecorderStatus.RECORDING, bag="/bags/recorded", messages=tick))
            value = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=tick)
            source.publish(ROBOT, "/parameter_events", ParameterEvent(
                node="/rec1/detector",
                changed_parameters=[Parameter(name="threshold", value=value)]))

    registry.load_views()
    policy = AccessPolicy.for_server()
    shell = Shell(source=source, policy=policy, layout=Layout(), layout_path=None)
    shell.layout = Layout(panels=(
        Panel("recorder", ROBOT), Panel("parameters", ROBOT, (("node", "detector"),)),
        Panel("image", ROBOT)))
    install(shell)
    port = free_port(policy.host)
    app.on_startup(lambda: print(f"debug_gui: serving a recorded log at {url(policy, port)}",
                                 flush=True))
    feeder = threading.Thread(target=replay, daemon=True)
    feeder.start()
    try:
        ui.run(host=policy.host, port=port, reload=False, show=False,
               show_welcome_message=False, uvicorn_logging_level="warning")
    finally:
        stop.set()
    return 0


if __name__ == "__main__":
    sys.exit(main())
