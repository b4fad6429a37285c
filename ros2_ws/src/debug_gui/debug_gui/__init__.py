"""debug_gui: an integrated debugging GUI for teams of robots, live in the browser.

Where things live (ARCHITECTURE.md, "debug_gui", has the why):

* ``hub``       the data side: one rclpy context per DDS domain, robot discovery, feeds
                (throttled at the robot where it can), service calls; no UI toolkit;
* ``source``    the ``Source`` protocol every model takes: the live Hub or a log's playback;
* ``playback``  ``Playback``: a merged team log as a Source, one cursor in log time;
* ``robots``    ``RobotId`` (domain, namespace, how it is reached);
* ``models/``   one module per view kind, the view's data (tested without a browser);
* ``ui/``       NiceGUI: the view kinds' registry, the shell (binding, clone, team layout,
                layouts), one module per view kind;
* ``params``    the rcl_interfaces parameter client (the parameters view and the Foxglove
                endpoint share it);
* ``security``  bind address, token, validation; ``server`` the ``debug_gui`` command;
  ``demo`` several simulated robots and the GUI.

Public names are re-exported here; the UI is imported only by ``server`` and ``ui``.
"""

from typing import TYPE_CHECKING

from efficient_comm.lazy import lazy_exports

#: Each public name and the module that defines it, imported on first use: the commands
#: (``debug_gui``, the demo) answer a bad option before the data side is imported.
_EXPORTS: dict[str, str] = {
    "AccessDenied": ".errors",
    "CallFailed": ".errors",
    "DebugGuiError": ".errors",
    "InvalidInput": ".errors",
    "LogUnreadable": ".errors",
    "NotLive": ".errors",
    "RobotUnavailable": ".errors",
    "Feed": ".hub",
    "Hub": ".hub",
    "TopicCounter": ".hub",
    "Playback": ".playback",
    "RobotId": ".robots",
    "AccessPolicy": ".security",
    "Source": ".source",
    "Stream": ".source",
}
__all__ = sorted([*_EXPORTS, "main"])

if not TYPE_CHECKING:  # hidden from type checkers, which would take any name as valid
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
else:  # the same names for type checkers (tests/test_lazy_exports.py keeps both alike)
    from .errors import AccessDenied as AccessDenied
    from .errors import CallFailed as CallFailed
    from .errors import DebugGuiError as DebugGuiError
    from .errors import InvalidInput as InvalidInput
    from .errors import LogUnreadable as LogUnreadable
    from .errors import NotLive as NotLive
    from .errors import RobotUnavailable as RobotUnavailable
    from .hub import Feed as Feed
    from .hub import Hub as Hub
    from .hub import TopicCounter as TopicCounter
    from .playback import Playback as Playback
    from .robots import RobotId as RobotId
    from .security import AccessPolicy as AccessPolicy
    from .source import Source as Source
    from .source import Stream as Stream

def main() -> int:
    """The ``debug_gui`` command (imports the UI toolkit only when run)."""
    from .server import main as server_main

    return server_main()
