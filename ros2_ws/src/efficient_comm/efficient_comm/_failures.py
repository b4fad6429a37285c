"""What happens when a component's callback raises: logged so that it is read, answered so
that a service's caller knows.

A callback that raises on every call (a sensor unplugged, a bug on a hot path) would print
a traceback per call, burying everything else in the log. So each kind of failure (type and
place) of a callback is logged once in full; repeats are summed up at most every
:data:`SUMMARY_INTERVAL_NS`, with counts. ``stats()`` counts every one.

ROS 2 services have no error channel, so a service callback that raises cannot send an
exception to its caller. Answering with an empty response, which looks like a real answer,
would be the worst choice. Instead the caller gets a response that says the call failed
when the service type has a ``success`` field (most do: ``std_srvs/Trigger``, ``SetBool``,
our own), with the reason in its ``message``-like field; otherwise no response at all (a
caller in the same process gets the exception on its future), as from an rclpy service
whose callback raised.
"""

from __future__ import annotations

import sys
import traceback
from typing import TYPE_CHECKING, Any

from .errors import ServiceFailedError
from .typenames import type_name

if TYPE_CHECKING:
    from .handle import Logger
    from .stats import CallbackStats

#: After the first traceback of a failure, repeats are summed up at most this often.
SUMMARY_INTERVAL_NS = 10_000_000_000
#: Kinds of failure logged in full per callback; beyond, only summaries.
MAX_KINDS = 8
#: Response fields that carry the reason of a failed call, first match wins.
REASON_FIELDS = ("message", "error_message", "reason", "error")


def report_failure(stats: CallbackStats | None, logger: Logger | None, what: str,
                   now_ns: int) -> None:
    """Count and log the exception being handled in callback ``what`` (inside ``except``).

    ``now_ns`` is any monotonic time (the executor's clock on a manual clock, so summaries
    in tests follow ``advance``).
    """
    exc = sys.exc_info()[1]
    if stats is None:  # not a component callback (a queued call): log it, nothing to limit
        if logger is not None:
            logger.error(f"{what} raised:\n{traceback.format_exc().rstrip()}")
        return
    stats.exceptions += 1
    if logger is None or exc is None:
        return
    frames = traceback.extract_tb(exc.__traceback__)
    place = (frames[-1].filename, frames[-1].lineno or 0) if frames else ("", 0)
    kind = (type(exc).__qualname__, *place)
    failures = stats.failures
    if kind not in failures.kinds and len(failures.kinds) < MAX_KINDS:
        failures.kinds.add(kind)
        if not failures.kinds_logged:
            failures.logged_ns = now_ns
        failures.kinds_logged += 1
        logger.error(f"{what} raised:\n{traceback.format_exc().rstrip()}")
        return
    failures.repeats += 1
    if now_ns - failures.logged_ns >= SUMMARY_INTERVAL_NS:
        logger.error(
            f"{what} raised {type(exc).__name__}: {exc} (and {failures.repeats - 1} more "
            f"since its last report, {stats.exceptions} in all; tracebacks of the first ones "
            f"above; summaries at most every {SUMMARY_INTERVAL_NS / 1e9:g} s)"
        )
        failures.repeats = 0
        failures.logged_ns = now_ns


class FailureLog:
    """Per callback: the kinds of failure already logged in full and repeats since."""

    __slots__ = ("kinds", "kinds_logged", "logged_ns", "repeats")

    def __init__(self) -> None:
        self.kinds: set[tuple[str, str, int]] = set()
        self.kinds_logged = 0
        self.logged_ns = 0
        self.repeats = 0


def failure_response(srv_type: type, service: str, exc: BaseException) -> Any | None:
    """The response telling a caller that ``service`` failed, or None if its type cannot."""
    response = getattr(srv_type, "Response")()  # noqa: B009
    fields: dict[str, str] = response.get_fields_and_field_types()
    if fields.get("success") != "boolean":
        return None
    response.success = False
    for name in REASON_FIELDS:
        if fields.get(name) == "string":
            setattr(response, name, f"service {service} failed: {exc!r}")
            break
    return response


def failure_outcome(srv_type: type) -> str:
    """What a caller of a service of ``srv_type`` gets when its callback raises (for logs)."""
    fields = getattr(srv_type, "Response")().get_fields_and_field_types()  # noqa: B009
    if fields.get("success") == "boolean":
        return "its caller gets success=False"
    return f"{type_name(srv_type)} has no success field: its caller gets no answer"


def local_failure(service: str, exc: BaseException) -> ServiceFailedError:
    """What an in-process caller's future holds when there is no failure response."""
    error = ServiceFailedError(f"service {service} failed: {exc!r}")
    error.__cause__ = exc
    return error


def without_answer(rclpy_service: Any) -> None:
    """Make an rclpy service send nothing for a callback result of None.

    rclpy sends whatever the callback returns (and raises on None); a failed call with no
    failure response must stay unanswered instead.
    """
    send = rclpy_service.send_response

    def send_response(response: Any, header: Any) -> None:
        if response is not None:
            send(response, header)

    rclpy_service.send_response = send_response
