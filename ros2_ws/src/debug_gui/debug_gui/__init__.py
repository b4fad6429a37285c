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
