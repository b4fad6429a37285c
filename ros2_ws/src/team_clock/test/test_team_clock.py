"""Clock offsets between robots: the estimator, and the ClockSync exchange in a simulated team.

The team: the reference robot ``ref`` (its clock defines team time, itself 1 s off the
simulated true time), ``a`` (+250 ms, +50 ppm) linked to ``ref``, ``b`` (-400 ms, -50 ppm)
linked only to ``a``, and ``lone`` linked to nobody who knows the reference.
"""

from __future__ import annotations

import random

import pytest

from efficient_comm import from_msg
from efficient_comm.testing import TestHandle, test_container
from team_clock.estimator import OffsetEstimator, Sample, _feasible_range
from team_clock.sync import OFFSET_QOS, ClockSync
from team_clock.testing import SimDelay, SimTeam
from team_clock_interfaces.msg import ClockOffset

MS = 1_000_000
SKEWS = {"ref": (1000 * MS, 0.0), "a": (250 * MS, 50.0), "b": (-400 * MS, -50.0),
         "lone": (30 * MS, 10.0), "other": (0, 0.0)}
LINKS = [("ref", "a"), ("a", "b"), ("lone", "other")]


def _team(*, loss: float = 0.2, seed: int = 1, jitter_s: float = 0.002) -> SimTeam:
    return SimTeam(SKEWS, reference="ref", links=LINKS, loss=loss, seed=seed,
                   delay=SimDelay(min_s=0.001, jitter_s=jitter_s))


# -- estimator (no ROS) --------------------------------------------------------------------


def _exchange(rng: random.Random, true_offset: float, drift: float, t_local: int,
              *, out_s: float, back_s: float) -> Sample:
    """A round trip at local time ``t_local`` against a reference ``offset + drift*t`` ahead."""
    def ref(local: float) -> int:
        return round(local + true_offset + drift * local)

    t1 = t_local
    t2 = ref(t1 + out_s * 1e9)
    t3 = t2 + rng.randrange(0, 50_000)  # server processing time
    t4 = round(t1 + out_s * 1e9 + (t3 - t2) / (1 + drift) + back_s * 1e9)
    return Sample(t1, t2, t3, t4)


def test_symmetric_delays_give_exact_offset_and_drift() -> None:
    rng = random.Random(0)
    est = OffsetEstimator()
    for i in range(20):
        est.add(_exchange(rng, 5 * MS, 20e-6, i * 1_000_000_000, out_s=0.003, back_s=0.003))
    at = 20_000_000_000
    e = est.estimate(at)
    assert e is not None
    truth = 5 * MS + 20e-6 * at
    assert abs(e.offset_ns - truth) < 2_000
    assert e.drift_ppm == pytest.approx(20.0, abs=0.2)
    assert abs(e.offset_ns - truth) <= e.uncertainty_ns


@pytest.mark.parametrize("seed", range(5))
def test_asymmetric_random_delays_stay_within_the_stated_uncertainty(seed: int) -> None:
    rng = random.Random(seed)
    est = OffsetEstimator()
    drift = -73e-6
    for i in range(60):
        est.add(_exchange(rng, -400 * MS, drift, i * 500_000_000,
                          out_s=0.001 + rng.expovariate(1 / 0.004),
                          back_s=0.001 + rng.expovariate(1 / 0.004)))
        e = est.estimate(i * 500_000_000 + 250_000_000)
        assert e is not None
        truth = -400 * MS + drift * e.stamp_ns
        assert abs(e.offset_ns - truth) <= e.uncertainty_ns, (i, e)


def test_drift_is_measured_over_a_minute_of_moderate_jitter() -> None:
    rng = random.Random(7)
    est = OffsetEstimator()
    for i in range(120):
        est.add(_exchange(rng, 80 * MS, -73e-6, i * 500_000_000,
                          out_s=0.0005 + rng.expovariate(1 / 0.0005),
                          back_s=0.0005 + rng.expovariate(1 / 0.0005)))
    e = est.estimate(60_000_000_000)
    assert e is not None
    assert e.drift_ppm == pytest.approx(-73.0, abs=5.0)


def test_impossible_samples_are_refused_and_counted() -> None:
    est = OffsetEstimator()
    assert est.estimate(0) is None
    assert not est.add(Sample(t1=100, t2=50, t3=40, t4=200))  # server answered before asked
    assert not est.add(Sample(t1=100, t2=0, t3=10_000_000, t4=200))  # negative round trip
    assert est.rejected == 2 and len(est) == 0
    assert est.add(Sample(t1=100, t2=1150, t3=1160, t4=210))
    e = est.estimate(210)
    assert e is not None and e.samples == 1


def _steady(t: int, offset: int) -> Sample:
    return Sample(t, t + offset + 100_000, t + offset + 100_000, t + 200_000)


def test_a_clock_step_is_followed_once_confirmed() -> None:
    """The reference's time jumps by 5 ms: one sample is not believed, four are."""
    est = OffsetEstimator()
    s = 1_000_000_000
    for i in range(10):
        est.add(_steady(i * s, 0))
    est.add(_steady(10 * s, 5 * MS))  # a lone jump: held back
    e = est.estimate(10 * s)
    assert e is not None and abs(e.offset_ns) < 50_000
    for i in range(11, 14):
        est.add(_steady(i * s, 5 * MS))
    assert _feasible_range(list(est._samples), 14 * s, 200.0) is None
    e = est.estimate(14 * s)
    assert e is not None
    assert abs(e.offset_ns - 5 * MS) <= e.uncertainty_ns < 1 * MS
    assert est.inconsistent > 0 and len(est) == 4  # the old clock is forgotten


def test_feasible_range_holds_the_truth_and_is_tight() -> None:
    rng = random.Random(3)
    samples = [_exchange(rng, 2 * MS, 30e-6, i * 1_000_000_000, out_s=0.001,
                         back_s=0.001 + rng.random() * 0.002) for i in range(30)]
    at = 30_000_000_000
    feasible = _feasible_range(samples, at, 200.0)
    assert feasible is not None
    low, high = feasible
    assert low <= 2 * MS + 30e-6 * at <= high
    assert high - low < 2 * max(s.bound_ns for s in samples)


@pytest.mark.parametrize("drift_ppm", [50.0, 50.1, 50.25, -12.3])
@pytest.mark.parametrize("one_way_ns", [2_000, 5_000])
def test_a_fast_link_with_any_drift_is_consistent(drift_ppm: float, one_way_ns: int) -> None:
    """Round trips of microseconds allow drifts narrower than the scan's grid step.

    Whatever the drift (on a grid point or between two), one line explains every sample:
    nothing is taken for a clock step, no sample is forgotten, the bound holds.
    """
    est = OffsetEstimator()
    drift = drift_ppm * 1e-6
    for i in range(60):
        t1 = i * 1_000_000_000
        t2 = round(t1 + one_way_ns + 5 * MS + drift * (t1 + one_way_ns))
        t4 = t1 + 2 * one_way_ns + 1_000
        est.add(Sample(t1, t2, t2 + 1_000, t4))
        e = est.estimate(t4)
        assert e is not None
        assert abs(e.offset_ns - (5 * MS + drift * t4)) <= e.uncertainty_ns, (i, e)
    assert est.inconsistent == 0 and len(est) == 60
    assert e is not None and e.uncertainty_ns < 2 * one_way_ns + 1_000  # tight link, tight bound


def test_old_samples_leave_the_window() -> None:
    est = OffsetEstimator(window_ns=10_000_000_000)
    est.add(Sample(0, 5_000, 5_000, 10_000))
    assert est.estimate(5_000_000_000) is not None
    assert est.estimate(20_000_000_000) is None


# -- the exchange in a simulated team --------------------------------------------------------


@pytest.mark.parametrize("loss", [0.0, 0.3])
def test_team_estimates_hold_within_their_uncertainty(loss: float) -> None:
    team = _team(loss=loss)
    team.advance(10.0)
    worst: dict[str, int] = {"a": 0, "b": 0}
    for _ in range(160):
        team.advance(0.25)
        for robot in worst:
            err, unc = team.error_ns(robot), team.uncertainty_ns(robot)
            assert err is not None and unc is not None, robot
            assert abs(err) <= unc, (robot, err, unc)
            worst[robot] = max(worst[robot], abs(err))
    # Sub-millisecond over a jittery link (1 ms + 2 ms mean exponential each way), even
    # through a relay; and the relay is what b is synchronised through.
    assert worst["a"] < 1 * MS and worst["b"] < 1 * MS, worst
    a, b = team.syncs["a"].state, team.syncs["b"].state
    assert a is not None and b is not None
    assert (a.source, a.hops, a.path) == ("ref", 1, ("ref", "a"))
    assert (b.source, b.hops, b.path) == ("a", 2, ("ref", "a", "b"))
    assert a.estimate.uncertainty_ns < b.estimate.uncertainty_ns  # accumulated over the hop
    # Drift against the reference: a runs 50 ppm fast (reference rate 1 - 50e-6 of its own).
    assert a.estimate.drift_ppm == pytest.approx(-50.0, abs=20.0)
    assert b.estimate.drift_ppm == pytest.approx(50.0, abs=20.0)
    if loss:
        assert team.net.counts["lost"] > 0
        assert team.syncs["b"].counts["unanswered"] > 0
    assert team.syncs["a"].counts["loop"] > 0  # b's answers to a are refused


def test_robot_without_a_path_reports_no_estimate() -> None:
    team = _team()
    watcher = TestHandle("watcher", container=team.container)
    offsets: list[ClockOffset] = []
    watcher.create_subscription(ClockOffset, "/lone/team_clock/offset", offsets.append,
                                qos=OFFSET_QOS)
    team.advance(30.0)
    assert team.syncs["lone"].state is None
    assert team.syncs["lone"].to_reference(0) is None
    assert len(offsets) >= 50
    assert not any(m.valid for m in offsets)
    assert all(m.offset_ns == 0 and m.uncertainty_ns == 0 for m in offsets)
    assert team.syncs["lone"].counts["unanswered"] > 0
    assert team.syncs["other"].counts["served"] == 0  # it has no estimate to give either
    assert any("no estimate" in text for _, text in _records(team, "lone"))


def _records(team: SimTeam, robot: str) -> list[tuple[str, str]]:
    for loaded in team.container.components():
        if loaded.full_node_name == f"/{robot}/clock_sync":
            return list(loaded.handle.logger.records)  # type: ignore[attr-defined]
    raise LookupError(robot)


def test_published_offsets_describe_the_estimate() -> None:
    team = _team(loss=0.0)
    watcher = TestHandle("watcher", container=team.container)
    got: dict[str, list[ClockOffset]] = {"ref": [], "a": [], "b": []}
    for robot, store in got.items():
        watcher.create_subscription(ClockOffset, f"/{robot}/team_clock/offset", store.append,
                                    qos=OFFSET_QOS)
    team.advance(20.0)
    ref = got["ref"][-1]
    assert (ref.valid, ref.robot, ref.reference, ref.offset_ns, ref.hops) == (
        True, "ref", "ref", 0, 0)
    for robot, hops in (("a", 1), ("b", 2)):
        msg = got[robot][-1]
        assert msg.valid and msg.robot == robot and msg.reference == "ref" and msg.hops == hops
        local = from_msg(msg.stamp)
        # The stamp is the robot's own clock; the offset maps it to the reference clock.
        assert local == team.clocks[robot].now_ns()
        assert abs(local + msg.offset_ns - team.reference_now()) <= msg.uncertainty_ns
        assert msg.samples >= 4


def test_losing_the_reference_ends_the_estimates_without_a_loop() -> None:
    team = _team(loss=0.0)
    team.advance(20.0)
    assert team.syncs["b"].state is not None
    team.net.cut("ref", "a")
    team.advance(30.0)  # longer than stale_after_s
    assert team.syncs["a"].state is None  # not synchronised through b (whose path holds a)
    assert team.syncs["b"].state is None


def test_a_better_source_wins() -> None:
    """b hears both the reference (over a slow link) and a: it follows the tighter one."""
    team = SimTeam(SKEWS, reference="ref", links=[("ref", "a"), ("a", "b"), ("ref", "b")],
                   delay=SimDelay(min_s=0.001, jitter_s=0.001), seed=3)
    team.advance(20.0)
    b = team.syncs["b"].state
    assert b is not None
    assert b.source == "ref" and b.hops == 1  # direct beats relayed when links are alike


def test_clock_sync_needs_a_reference() -> None:
    with pytest.raises(ValueError, match="reference"):
        ClockSync(TestHandle("clock_sync"))


@pytest.mark.parametrize("bad", [{"period_s": 0.0}, {"window_s": -1.0},
                                 {"stale_after_s": 0.0}, {"max_hops": 0}])
def test_clock_sync_refuses_parameters_that_would_silently_never_sync(
        bad: dict[str, float]) -> None:
    with pytest.raises(ValueError, match=next(iter(bad))):
        ClockSync(TestHandle("clock_sync", parameters={"reference": "ref", **bad}))


def test_misconfigured_teams_are_reported() -> None:
    """Two robots named alike, and a robot expecting another reference: counted, logged."""
    team = SimTeam({"ref": (0, 0.0), "a": (5 * MS, 0.0)}, reference="ref",
                   links=[("ref", "a")], delay=SimDelay(min_s=0.001, jitter_s=0.0))
    twin = TestHandle("twin", container=team.container,
                      remappings={"/team_clock/ping": "/sim_net/a/ping",
                                  "/team_clock/pong": "/sim_net/a/pong",
                                  "/team_clock/offset": "/twin/team_clock/offset"},
                      parameters={"robot": "a", "reference": "other_ref"})
    imposter = ClockSync(twin)
    team.advance(5.0)
    assert team.syncs["a"].counts["name_clash"] > 0
    assert imposter.counts["other_reference"] > 0 and imposter.state is None
    assert any("also calls itself" in text for _, text in _records(team, "a"))
    assert any("synchronised to" in text for _, text in twin.records)


def test_loads_from_a_container_file_by_entry_point(tmp_path) -> None:
    config = tmp_path / "robot.yaml"
    config.write_text(
        "components:\n"
        "  - class: clock_sync\n"
        "    name: clock_sync\n"
        "    namespace: /robot_r\n"
        "    parameters:\n"
        "      /**:\n"
        "        ros__parameters: {reference: robot_r, period_s: 0.5}\n"
    )
    container = test_container()
    report = container.load_file(config)
    assert not report.errors, report.errors
    sync = report.loaded[0].instance
    assert isinstance(sync, ClockSync)
    assert sync.robot == "robot_r" and sync.is_reference  # named after its namespace
    watcher = TestHandle("watcher", container=container)
    got: list[ClockOffset] = []
    watcher.create_subscription(ClockOffset, "/team_clock/offset", got.append, qos=OFFSET_QOS)
    container.advance(1.0)
    assert got and got[-1].valid and got[-1].robot == "robot_r" and got[-1].hops == 0
