"""Options and the per-subscriber gate: validation, combination, rates, demand."""

from __future__ import annotations

import math
import random

import pytest

from throttle_publisher import (
    Gate,
    InvalidOptionsError,
    ThrottleOptions,
    from_wire,
    options_from_msg,
    request_msg,
)

MS = 1_000_000


def _run(options: ThrottleOptions, *, rate_hz: float, seconds: float, jitter_ms: float = 0.0,
         seed: int = 1) -> list[int]:
    """Offer a source of ``rate_hz`` to a gate; indices of the samples it took."""
    rng = random.Random(seed)
    gate = Gate(options)
    period = 1e9 / rate_hz
    taken = []
    for i in range(round(seconds * rate_hz)):
        now = round(i * period + rng.uniform(-jitter_ms, jitter_ms) * MS) + 10**12
        if gate.offer(now):
            taken.append(i)
    return taken


@pytest.mark.parametrize(
    "kwargs",
    [
        {"max_rate_hz": -1.0},
        {"max_rate_hz": math.nan},
        {"max_rate_hz": math.inf},
        {"max_rate_hz": "fast"},
        {"every_nth": 0},
        {"every_nth": 2.5},
        {"every_nth": True},
        {"paused": "yes"},
    ],
)
def test_invalid_options_are_rejected_when_created(kwargs: dict[str, object]) -> None:
    with pytest.raises(InvalidOptionsError):
        ThrottleOptions(**kwargs)  # type: ignore[arg-type]


def test_unknown_options_cannot_be_created() -> None:
    with pytest.raises(TypeError):
        ThrottleOptions(max_rate=5.0)  # type: ignore[call-arg]


def test_wire_round_trip_and_forward_compatibility() -> None:
    options = ThrottleOptions(max_rate_hz=5.0, every_nth=3, paused=True)
    back, warnings = from_wire(options.to_wire())
    assert back == options and warnings == []
    assert ThrottleOptions().to_wire() == []  # defaults are not sent
    newer, warnings = from_wire([("max_rate_hz", 2.0), ("min_distance_m", 0.5)])
    assert newer == ThrottleOptions(max_rate_hz=2.0)
    assert warnings == ["unknown throttle option 'min_distance_m' ignored"]


def test_request_message_carries_the_options() -> None:
    from efficient_comm_interfaces.msg import ThrottleOption

    options = ThrottleOptions(max_rate_hz=2.0, every_nth=4)
    msg = request_msg("sub-1", "/camera/image", options)
    assert (msg.subscriber_id, msg.topic) == ("sub-1", "/camera/image")
    assert options_from_msg(msg) == (options, [])
    msg.options.append(ThrottleOption(name="future_option", value=1.0))
    assert options_from_msg(msg)[1] == ["unknown throttle option 'future_option' ignored"]


@pytest.mark.parametrize(
    "pairs",
    [
        [("max_rate_hz", -3.0)],
        [("max_rate_hz", math.nan)],
        [("every_nth", 0.0)],
        [("every_nth", 2.5)],
        [("paused", 0.5)],
        [("every_nth", 2.0), ("every_nth", 3.0)],
    ],
)
def test_invalid_values_from_the_wire_are_rejected(pairs: list[tuple[str, float]]) -> None:
    with pytest.raises(InvalidOptionsError):
        from_wire(pairs)


def test_defaults_take_everything_and_pause_takes_nothing() -> None:
    assert len(_run(ThrottleOptions(), rate_hz=30, seconds=2)) == 60
    assert ThrottleOptions().unlimited
    assert _run(ThrottleOptions(paused=True), rate_hz=30, seconds=2) == []


def test_every_nth_counts_source_samples() -> None:
    assert _run(ThrottleOptions(every_nth=10), rate_hz=30, seconds=2) == [0, 10, 20, 30, 40, 50]


@pytest.mark.parametrize(
    ("source", "asked"), [(30, 5), (30, 10), (30, 20), (100, 7), (30, 30), (30, 12), (30, 25)]
)
def test_max_rate_is_never_exceeded_and_jitter_costs_little(source: int, asked: float) -> None:
    seconds = 20
    for jitter in (0.0, 2.0):
        taken = _run(ThrottleOptions(max_rate_hz=asked), rate_hz=source, seconds=seconds,
                     jitter_ms=jitter)
        rate = len(taken) / seconds
        assert rate <= asked + 1 / seconds  # one sample of slack at the start
        # Where the source's rate is a multiple of the request, nothing is lost to jitter;
        # otherwise aliasing between the two rates may cost a little.
        floor = asked if source % asked == 0 else asked * 0.9
        assert rate >= floor * 0.99, (source, asked, jitter, rate)


def test_options_combine_as_documented() -> None:
    both = ThrottleOptions(every_nth=10, max_rate_hz=1.0)
    taken = _run(both, rate_hz=30, seconds=10)
    assert taken == list(range(0, 300, 30))  # every 30th on a 30 Hz source
    slow = _run(both, rate_hz=5, seconds=10)
    assert slow == list(range(0, 50, 10))  # every 10th on a 5 Hz source (0.5 Hz)


def test_demand_query_does_not_change_state() -> None:
    gate = Gate(ThrottleOptions(max_rate_hz=10.0))
    now = 10**12
    assert gate.wants(now) and gate.wants(now)
    assert gate.offer(now)
    assert not gate.wants(now + 10 * MS)
    due = gate.next_due_ns(now + 10 * MS)
    assert due is not None and now + 10 * MS < due <= now + 100 * MS
    assert gate.wants(due)
    assert Gate(ThrottleOptions(paused=True)).next_due_ns(now) is None


def test_run_time_change_applies_at_once() -> None:
    gate = Gate(ThrottleOptions(paused=True))
    now = 10**12
    assert not gate.offer(now)
    gate.update(ThrottleOptions(every_nth=2))
    assert [gate.offer(now + i * MS) for i in range(4)] == [True, False, True, False]
