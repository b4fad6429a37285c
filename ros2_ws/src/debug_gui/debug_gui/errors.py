"""debug_gui's errors: one root, so a caller can catch everything the GUI raises at once.

Tree (other views append their subclasses at the end, one class per block)::

    DebugGuiError(Exception)
    ├── AccessDenied(PermissionError)      a write without the right token
    ├── InvalidInput(ValueError)           a name, value, option or layout that is malformed
    │   └── LayoutConflict                 the saved layout changed since this tab loaded it
    ├── RobotUnavailable(LookupError)      no such robot, service or domain (or it went away)
    ├── CallFailed                         a service call that timed out or failed
    ├── NotLive                            a call a recorded log cannot answer (playback)
    └── LogUnreadable                      a log to play back that cannot be read (damaged)
"""

from __future__ import annotations

#: What a view says where a log cannot do what the robot could (every NotLive names it).
NOT_LIVE = "recorded: not live"


class DebugGuiError(Exception):
    """Root of every error debug_gui raises on purpose."""


class AccessDenied(DebugGuiError, PermissionError):  # noqa: N818 (the views' contract names them)
    """A write (parameters, recorder control, saving a layout) without the server's token."""


class InvalidInput(DebugGuiError, ValueError):  # noqa: N818 (the views' contract names them)
    """Input from a browser, a layout file or the command line that is malformed."""


class RobotUnavailable(DebugGuiError, LookupError):  # noqa: N818 (the views' contract names them)
    """The robot, its domain or the service asked for is not (or no longer) there."""


class CallFailed(DebugGuiError):  # noqa: N818 (the views' contract names them)
    """A service call that got no answer in time, or whose answer could not be had."""


class LayoutConflict(InvalidInput):
    """A save that would silently replace a saved layout this tab never saw (another tab,
    or another server, saved a different one since this tab loaded its own)."""


class NotLive(DebugGuiError):  # noqa: N818 (the views' contract names them)
    """A service call (parameters, recorder control) made of a log played back: a log
    answers only with what it recorded."""


class LogUnreadable(DebugGuiError):  # noqa: N818 (the views' contract names them)
    """A log given to play back (``debug_gui --log``) that cannot be read: missing, not a
    bag, damaged, empty. The message says which file and why."""
