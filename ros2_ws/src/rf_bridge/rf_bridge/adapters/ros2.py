"""The ROS 2 side: the bridge as an efficient_comm component.

Written against the node handle, so it runs standalone (``rf_bridge --ros-args -p
config:=bridge.yaml``), composed in a container next to the components it serves (then ROS
2 messages reach it by reference, no serialisation on the ROS 2 side), or under
``TestHandle``. Adapter threads publish into ROS 2 from their own threads; the composed
executor queues such messages and runs subscribers in its own thread.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from efficient_comm import to_msg
from efficient_comm.handle import NodeHandle, Publisher

from ..config import BridgeConfig, TopicSpec, load_config
from ..core.adapter import ChannelAdapter, Route
from ..core.budget import LinkUsage
from ..core.router import Router
from ..core.stats import TopicStats, TopicStatsSnapshot
from ..errors import ConfigError, RfBridgeError
from ..translate import TranslatorSet, ros2_class


class BridgeNode:
    """The bridge: routes configured topics between ROS 2 and the configured systems.

    ``config`` (a :class:`BridgeConfig`) wins over the ``config`` parameter (a file path).
    ``adapters`` replaces the adapters built from the configuration (tests, other systems).
    """

    def __init__(
        self,
        node: NodeHandle,
        *,
        config: BridgeConfig | None = None,
        adapters: Mapping[str, ChannelAdapter] | None = None,
    ) -> None:
        self._node = node
        if config is None:
            path = node.declare_parameter("config", "")
            if not path:
                raise ConfigError("rf_bridge needs a bridge file: -p config:=bridge.yaml")
            config = load_config(path)
        for error in config.errors:
            node.logger.error(error)
        self.config = config
        self.translators = TranslatorSet(config.rules)
        self.adapters: dict[str, ChannelAdapter] = dict(adapters or self._build_adapters(config))
        self._publishers: dict[int, Publisher] = {}
        self.routes: list[Route] = []
        # Throttling shapes traffic on real links, so it runs on the monotonic clock even
        # when the node's clock is simulated or manual.
        self.router = Router(self.adapters, publish=self._publish, now_ns=time.monotonic_ns)
        wanted: list[Route] = []
        for spec in config.topics:
            try:
                route = self._route(spec)
                if spec.inbound:  # before any adapter starts: a peer may send at once
                    self._publishers[id(route)] = node.create_publisher(
                        route.ros2_cls, spec.ros2_topic, qos=spec.qos
                    )
            except (RfBridgeError, ValueError, TypeError) as exc:
                node.logger.error(f"topic {spec.ros2_topic} not bridged: {exc}")
                continue
            wanted.append(route)
        for name, adapter in self.adapters.items():
            mine = [r for r in wanted if r.spec.peer == name]
            served = {id(r) for r in adapter.start(mine, self.router.from_peer)}
            self.routes += [r for r in mine if id(r) in served]
        self._throttled: list[Any] = []
        refused = [r for r in wanted if r not in self.routes]
        for route in refused:  # the adapter said why
            publisher = self._publishers.pop(id(route), None)
            if publisher is not None:
                node.destroy_publisher(publisher)
        for route in self.routes:
            self.router.add(route)
            if route.spec.outbound:
                self._subscribe(route)
        skipped = len(config.errors) + len(config.topics) - len(self.routes)
        node.logger.info(
            f"rf_bridge: {len(self.routes)} topic(s) bridged with {sorted(self.adapters)}"
            + (f"; {skipped} not bridged (see above)" if skipped else "")
        )
        if config.stats_period_s > 0:
            node.create_timer(config.stats_period_s, self.log_stats)
        self._diagnostics: Publisher | None = None
        if config.usage_period_s > 0 and self.link_usage():
            self._diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", qos=10)
            node.create_timer(config.usage_period_s, self.publish_usage)

    def lockstep_team_link(self, barrier: Any, *, peers: Sequence[str],
                           latency_s: float) -> None:
        """The team link delivers deterministically in lockstep (``barrier``: the
        container's ``lockstep`` participant; see :meth:`.team.TeamAdapter.attach_lockstep`).
        Without a team link, nothing to do."""
        adapter = self.adapters.get("team")
        attach = getattr(adapter, "attach_lockstep", None)
        if callable(attach):
            attach(barrier, peers=peers, latency_s=latency_s)

    def _build_adapters(self, config: BridgeConfig) -> dict[str, ChannelAdapter]:
        out: dict[str, ChannelAdapter] = {}
        peers = {t.peer for t in config.topics}
        if config.ros1 is not None and "ros1" in peers:
            from .ros1.adapter import Ros1Adapter

            out["ros1"] = Ros1Adapter(config.ros1, self.translators, self._node.logger)
        if config.team is not None and "team" in peers:
            from .team import TeamAdapter

            # Under simulated time the budget is per simulated second (what a lockstep run
            # admits then repeats); otherwise per wall second.
            clock = self._node.clock
            now_ns = clock.now_ns if self._node.clock_kind == "sim" else time.monotonic_ns
            out["team"] = TeamAdapter(config.team, self._node.logger, now_ns=now_ns)
        return out

    def _route(self, spec: TopicSpec) -> Route:
        if spec.peer not in self.adapters:
            raise ConfigError(f"no adapter for peer {spec.peer!r}")
        if spec.ros2_type is not None:
            cls = ros2_class(spec.ros2_type)
        elif spec.peer_type is not None:
            cls = self.translators.ros2_class_for(spec.peer_type)
        else:  # config.py requires one of them
            raise ConfigError(f"{spec.ros2_topic}: no type")
        return Route(
            spec=spec,
            ros2_cls=cls,
            stats_out=TopicStats(spec.ros2_topic, f"to_{spec.peer}"),
            stats_in=TopicStats(spec.ros2_topic, f"from_{spec.peer}"),
        )

    def _subscribe(self, route: Route) -> None:
        spec = route.spec

        def callback(msg: Any, route: Route = route) -> None:
            self.router.from_ros2(route, msg)

        if spec.throttle is not None and spec.throttle_mode == "publisher":
            from throttle_publisher import ThrottledSubscription

            self._throttled.append(
                ThrottledSubscription(
                    self._node,
                    route.ros2_cls,
                    spec.ros2_topic,
                    callback,
                    options=spec.throttle,
                    qos=spec.qos,
                )
            )
        else:
            self._node.create_subscription(route.ros2_cls, spec.ros2_topic, callback, qos=spec.qos)

    def _publish(self, route: Route, msg: Any) -> None:
        self._publishers[id(route)].publish(msg)  # created before the adapters started

    def stats(self) -> list[TopicStatsSnapshot]:
        """Messages, bytes, drops by reason and latency, per topic and direction."""
        out = []
        for route in self.routes:
            if route.spec.outbound:
                out.append(route.stats_out.snapshot())
            if route.spec.inbound:
                out.append(route.stats_in.snapshot())
        return out

    def link_usage(self) -> list[LinkUsage]:
        """What crossed each link that counts its bytes (the team link), since its start."""
        out = []
        for adapter in self.adapters.values():
            usage = getattr(adapter, "usage", None)  # optional: links with a byte count
            if callable(usage):
                out.append(usage())
        return out

    def publish_usage(self) -> None:
        """The links' usage on ``/diagnostics``, one status per link (``rf_bridge: <link>
        link``, hardware id the robot id): the figures a match report reads back."""
        if self._diagnostics is None:
            return
        array = DiagnosticArray()
        array.header.stamp = to_msg(self._node.clock.now_ns())
        for u in self.link_usage():
            status = DiagnosticStatus(name=f"rf_bridge: {u.link} link", hardware_id=u.robot_id)
            status.level = DiagnosticStatus.WARN if u.over_budget else DiagnosticStatus.OK
            status.message = (f"{u.sent_bytes_per_s:.0f} B/s sent"
                              + (f", {u.over_budget} over budget" if u.over_budget else ""))
            figures = {
                "sent_bytes": u.sent_bytes, "sent_messages": u.sent_messages,
                "sent_bytes_per_s": round(u.sent_bytes_per_s, 1),
                "peak_bytes_per_s": u.peak_bytes_per_s,
                "received_bytes": u.received_bytes, "received_messages": u.received_messages,
                "over_budget": u.over_budget, "elapsed_s": round(u.elapsed_s, 3),
                "budget_bytes_per_s": u.budget_bytes_per_s or 0,
                "budget_burst_bytes": u.budget_burst_bytes or 0,
            }
            status.values = [KeyValue(key=k, value=str(v)) for k, v in figures.items()]
            array.status.append(status)
        self._diagnostics.publish(array)

    def log_stats(self) -> None:
        """One line per topic and direction: what crossed, what did not and why."""
        for s in self.stats():
            latency = f", latency {s.latency_median_us:.0f} us" if s.latency_median_us else ""
            drops = ", ".join(f"{k} {v}" for k, v in sorted(s.drops.items())) or "none"
            self._node.logger.info(
                f"{s.topic} {s.direction}: {s.messages} msgs, {s.bytes} B{latency}; drops: {drops}"
            )
        for u in self.link_usage():
            budget = f" of {u.budget_bytes_per_s:.0f}" if u.budget_bytes_per_s else ""
            self._node.logger.info(
                f"{u.link} link: {u.sent_bytes_per_s:.0f}{budget} B/s sent (peak "
                f"{u.peak_bytes_per_s} B in a second), {u.over_budget} over budget"
            )

    def close(self) -> None:
        """Close every adapter, even when one of them fails to (that one is logged)."""
        for name, adapter in self.adapters.items():
            try:
                adapter.close()
            except Exception as exc:
                self._node.logger.error(f"closing the {name} adapter raised {exc!r}")


def main(argv: Sequence[str] | None = None) -> int:
    """``rf_bridge --ros-args -p config:=bridge.yaml``: the bridge as its own process."""
    import argparse
    import sys

    from rclpy.utilities import remove_ros_args

    args = list(sys.argv if argv is None else argv)
    parser = argparse.ArgumentParser(
        prog="rf_bridge",
        usage="rf_bridge [-h] --ros-args -p config:=bridge.yaml",
        description="Bridge ROS 2 topics to a ROS 1 system and to other robots "
        "(docs/RF_BRIDGE.md).",
        epilog="The bridge file lists the topics, the ROS 1 master and the team link "
        "(format: docs/RF_BRIDGE.md, rf_bridge/config.py).",
    )
    parser.parse_args(remove_ros_args(args)[1:])
    from efficient_comm import run_standalone as run

    return run(BridgeNode, name="rf_bridge", args=args)
