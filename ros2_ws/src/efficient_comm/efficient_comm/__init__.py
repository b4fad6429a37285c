"""efficient_comm: write a ROS 2 node once, run it standalone, composed or under test.

Where things live (read ARCHITECTURE.md for the why):

* ``handle``     the node-handle interface components are written against (the gateway);
* ``standalone`` one component = one rclpy node = one process (``ros2 run``);
* ``container``  many components in one process, by reference, on the
  ``executor`` (consecutive, one thread) over the in-process ``bus``;
* ``testing``    a handle with no DDS and a manual clock, for users' own tests;
* ``config``     container files; ``dds`` keeping in-process and DDS delivery apart;
* ``shm``        large messages to same-machine processes through shared memory
                 (``Container(shm=True)``), DDS still for everyone else;
* ``guard``      finding callbacks that modify shared messages; ``stats`` callback timing
                 (``format_stats`` prints it), ``stats_publisher`` its topic for tools;
* ``simtime``    simulated time from another process (``/clock``) and the lockstep barrier
                 (``StepCoordinator``, the world's end, ``advance_together`` for robots on
                 several domains; ``Container(lockstep=...)``, a robot's);
* ``typenames`` type name <-> class (``pkg/msg/Name``), the one owner of that spelling;
* ``plain``      messages as plain trees (``to_plain``), as ``ros2 topic echo`` shows them;
* ``binding``    a parameter dataclass bound to the node's parameters (``bind_parameters``);
* ``from_msg``/``to_msg`` header stamp <-> integer nanoseconds; ``latched_qos`` the one
  latched profile;
* ``run_standalone``, ``stop_on_sigterm`` for programs and console scripts of their own.
* ``lazy``       a package's public names loaded on first use (``lazy_exports``; this
                 package's own, debug_gui's).

Everything public is re-exported here once; modules starting with ``_`` are private.
The re-exports are loaded on first use (:data:`_EXPORTS`): a tool that reads bags or
prints messages imports the type names, not the container, shared memory and numpy
(0.45 s of every ``ros2`` verb and every ``log_analysis`` command before).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .lazy import lazy_exports

#: Each public name and the module that defines it, imported when the name is first used.
_EXPORTS: dict[str, str] = {
    "ManualClock": "._clock",
    "SimClock": "._clock",
    "SkewedClock": "._clock",
    "SystemClock": "._clock",
    "from_msg": "._clock",
    "to_msg": "._clock",
    "Closing": "._closing",
    "latched_qos": "._qos",
    "matching_qos": "._qos",
    "exit_with_parent": "._signals",
    "stop_on_sigterm": "._signals",
    "BoundParameters": ".binding",
    "bind_parameters": ".binding",
    "ComponentSpec": ".config",
    "resolve_factory": ".config",
    "Container": ".container",
    "LoadedComponent": ".container",
    "LoadReport": ".container",
    "ComponentError": ".errors",
    "ConfigError": ".errors",
    "DdsSetupError": ".errors",
    "EfficientCommError": ".errors",
    "ExecutorError": ".errors",
    "LockstepError": ".errors",
    "MessageMutatedError": ".errors",
    "NameResolutionError": ".errors",
    "ParameterError": ".errors",
    "ServiceFailedError": ".errors",
    "TopicTypeError": ".errors",
    "UnknownTypeError": ".errors",
    "ConsecutiveExecutor": ".executor",
    "NodeHandle": ".handle",
    "abbreviate_array": ".plain",
    "element_type": ".plain",
    "is_message": ".plain",
    "to_plain": ".plain",
    "StepCoordinator": ".simtime",
    "advance_together": ".simtime",
    "Standalone": ".standalone",
    "run_standalone": ".standalone",
    "standalone_main": ".standalone",
    "StatsSnapshot": ".stats",
    "format_stats": ".stats",
    "STATS_TOPIC": ".stats_publisher",
    "StatsPublisher": ".stats_publisher",
    "import_type": ".typenames",
    "type_name": ".typenames",
}
__all__ = sorted(_EXPORTS)


if not TYPE_CHECKING:  # hidden from type checkers, which would take any name as valid
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
else:  # the same names for type checkers (tests/test_lazy_exports.py keeps both alike)
    from ._clock import ManualClock as ManualClock
    from ._clock import SimClock as SimClock
    from ._clock import SkewedClock as SkewedClock
    from ._clock import SystemClock as SystemClock
    from ._clock import from_msg as from_msg
    from ._clock import to_msg as to_msg
    from ._closing import Closing as Closing
    from ._qos import latched_qos as latched_qos
    from ._qos import matching_qos as matching_qos
    from ._signals import exit_with_parent as exit_with_parent
    from ._signals import stop_on_sigterm as stop_on_sigterm
    from .binding import BoundParameters as BoundParameters
    from .binding import bind_parameters as bind_parameters
    from .config import ComponentSpec as ComponentSpec
    from .config import resolve_factory as resolve_factory
    from .container import Container as Container
    from .container import LoadedComponent as LoadedComponent
    from .container import LoadReport as LoadReport
    from .errors import ComponentError as ComponentError
    from .errors import ConfigError as ConfigError
    from .errors import DdsSetupError as DdsSetupError
    from .errors import EfficientCommError as EfficientCommError
    from .errors import ExecutorError as ExecutorError
    from .errors import LockstepError as LockstepError
    from .errors import MessageMutatedError as MessageMutatedError
    from .errors import NameResolutionError as NameResolutionError
    from .errors import ParameterError as ParameterError
    from .errors import ServiceFailedError as ServiceFailedError
    from .errors import TopicTypeError as TopicTypeError
    from .errors import UnknownTypeError as UnknownTypeError
    from .executor import ConsecutiveExecutor as ConsecutiveExecutor
    from .handle import NodeHandle as NodeHandle
    from .plain import abbreviate_array as abbreviate_array
    from .plain import element_type as element_type
    from .plain import is_message as is_message
    from .plain import to_plain as to_plain
    from .simtime import StepCoordinator as StepCoordinator
    from .simtime import advance_together as advance_together
    from .standalone import Standalone as Standalone
    from .standalone import run_standalone as run_standalone
    from .standalone import standalone_main as standalone_main
    from .stats import StatsSnapshot as StatsSnapshot
    from .stats import format_stats as format_stats
    from .stats_publisher import STATS_TOPIC as STATS_TOPIC
    from .stats_publisher import StatsPublisher as StatsPublisher
    from .typenames import import_type as import_type
    from .typenames import type_name as type_name
