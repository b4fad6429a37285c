"""ros2_pip_cli: the ``ros2`` command for the pip (wheel) install of ROS 2 Jazzy.

ros2cli is published neither as wheels nor as a Debian 12 package, so this package offers its
most used verbs, with ros2cli's arguments and output formats where people script against
them. It is run as ``python -m ros2_pip_cli``; scripts/setup.sh writes a ``ros2`` launcher
into the project's venv only, so on a regular ROS 2 install the real ros2cli is used.

Where things live:

* ``_main``      the command line: commands, verbs, the error for what is not offered;
* ``_graph``     a daemon-free node that waits for discovery until the graph is stable;
* ``_timing``    how long commands listen (light: ``ros2 run`` and ``pkg`` import no rclpy);
* ``_view``      what the graph verbs print, from the daemon or from the command's own node;
* ``_daemon``    the per-user graph daemon (its process, socket and ``ros2 daemon``);
* ``_messages``  messages as YAML and CSV (``topic echo``);
* ``_fill``      YAML values into messages by the fields' types (``topic pub``, calls);
* ``_pkg``, ``_node``, ``_topic``, ``_service``, ``_param``, ``_interface``,
  ``_component``, ``_bag``: one module per command.

The public API is :func:`main` and the error tree in ``errors``, and for tests:
:data:`DAEMON_DIR_ENV` (the variable naming the daemons' folder) and :func:`stop_daemons`
(stop every daemon in a folder). What other tools share with ``topic echo`` (type names,
messages as plain trees) is efficient_comm's.
"""

from ._daemon import DAEMON_DIR_ENV as DAEMON_DIR_ENV
from ._daemon import stop_daemons as stop_daemons
from ._main import main as main
from .errors import CliError as CliError
from .errors import UsageError as UsageError
