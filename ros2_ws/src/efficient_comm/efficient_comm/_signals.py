"""Process signals: SIGTERM stops a program as Ctrl-C does."""

from __future__ import annotations

import contextlib
import ctypes
import signal
import sys
import threading
from collections.abc import Callable, Iterator

_PR_SET_PDEATHSIG = 1
_PRCTL = ctypes.CDLL(None, use_errno=True).prctl if sys.platform == "linux" else None


def exit_with_parent() -> None:
    """``preexec_fn`` for ``subprocess.Popen``: the child gets SIGTERM when the thread that
    started it ends, however that happens (SIGKILL included). A program that starts its
    peers in sessions of their own (so Ctrl-C reaches them one by one) would otherwise
    leave them running when it is killed: robots playing on in a DDS domain that the next
    user, or the next test, takes for free. Linux only; elsewhere it does nothing."""
    if _PRCTL is not None:
        _PRCTL(_PR_SET_PDEATHSIG, signal.SIGTERM)


def stop_on_sigterm() -> None:
    """Let SIGTERM (what ``ros2 launch`` and service managers send) unwind like Ctrl-C.

    For programs with a loop of their own (``spin_for`` and printing, say): SIGTERM raises
    ``KeyboardInterrupt`` from then on, so ``with`` blocks unload components and their
    ``close()`` runs, instead of the process dying mid-callback. ``Container.spin()``
    needs no call: it stops on SIGTERM by itself.
    """

    def interrupt(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)


@contextlib.contextmanager
def sigterm_calls(stop: Callable[[], None]) -> Iterator[None]:
    """While inside, SIGTERM calls ``stop()`` (between two callbacks, from the main thread).

    Only where Python can handle signals (the main thread) and only if SIGTERM still has
    its default action, which kills the process without running any ``close()``; a handler
    the program chose itself is left alone.
    """
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL
    ):
        yield
        return
    signal.signal(signal.SIGTERM, lambda _signum, _frame: stop())
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextlib.contextmanager
def interrupt_calls(stop: Callable[[], None]) -> Iterator[None]:
    """While inside, the first Ctrl-C (SIGINT) calls ``stop()``; a second one raises
    ``KeyboardInterrupt`` as usual (a callback that never returns can still be broken).

    Python raises ``KeyboardInterrupt`` at whatever bytecode the main thread runs; inside
    rclpy's conversion of a message it takes, pybind11 turns it into ``RuntimeError:
    Unable to convert call argument '0' to Python object``, and the program ends in that
    traceback instead of stopping (a loaded machine hits this window often). Only in the
    main thread, and only if SIGINT still raises ``KeyboardInterrupt``.
    """
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    interrupted = False

    def interrupt(_signum: int, _frame: object) -> None:
        nonlocal interrupted
        if interrupted:
            raise KeyboardInterrupt
        interrupted = True
        stop()

    signal.signal(signal.SIGINT, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
