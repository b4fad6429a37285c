"""Process signals for the console scripts."""

from __future__ import annotations

import signal


def stop_on_sigterm() -> None:
    """Let SIGTERM (what ``ros2 launch`` and service managers send) unwind like Ctrl-C.

    Components are then unloaded and their ``close()`` runs, instead of the process dying
    mid-callback.
    """

    def interrupt(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)
