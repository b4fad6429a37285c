"""The one exception root of ros2_pip_cli.

::

    CliError                 a one-line message for the user; the command exits with 1
    └── UsageError           a verb or option this install does not offer (exit 2)
"""

from __future__ import annotations


class CliError(Exception):
    """Something the user can act on; printed as one line, never as a traceback."""


class UsageError(CliError):
    """A verb or option this install does not offer; the message lists what it does offer."""
