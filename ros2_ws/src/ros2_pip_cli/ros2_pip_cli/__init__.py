"""ros2_pip_cli: the ``ros2`` command for the pip (wheel) install of ROS 2 Jazzy.

ros2cli is published neither as wheels nor as a Debian 12 package, so this package offers its
most used verbs, with ros2cli's arguments and output formats where people script against
them. It is run as ``python -m ros2_pip_cli``; scripts/setup.sh writes a ``ros2`` launcher
into the project's venv only, so on a regular ROS 2 install the real ros2cli is used.

Where things live:

* ``_main``      the command line: commands, verbs, the error for what is not offered;
* ``_graph``     a daemon-free node that waits for discovery until the graph is stable;
* ``_messages``  messages as YAML and CSV (``topic echo``);
* ``_fill``      YAML values into messages by the fields' types (``topic pub``, calls);
* ``_pkg``, ``_node``, ``_topic``, ``_service``, ``_param``, ``_interface``,
  ``_component``, ``_bag``: one module per command.

The public API is :func:`main`, the error tree in ``errors``, and the two message helpers
other tools share with ``topic echo`` (the debug GUI's topic view): :func:`import_interface`
(a type name to its class) and :func:`to_plain` (a message as dicts, lists and scalars).
"""

from ._main import main as main
from ._messages import import_interface as import_interface
from ._messages import to_plain as to_plain
from .errors import CliError as CliError
from .errors import UsageError as UsageError
