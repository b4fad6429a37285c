"""The one exception root of ros2_pip_cli.

::

    CliError                 a one-line message for the user; the command exits with 1
    ├── UsageError           a verb or option this install does not offer (exit 2)
    └── DaemonUnavailableError  no graph daemon can be used here (unsafe folder); the
                                graph verbs then answer without one
"""

from __future__ import annotations


class CliError(Exception):
    """Something the user can act on; printed as one line, never as a traceback."""


class UsageError(CliError):
    """A verb or option this install does not offer; the message lists what it does offer."""


class DaemonUnavailableError(CliError):
    """No graph daemon can be used here: its folder is not private, or the socket path is
    too long. Graph verbs warn and listen for themselves."""
