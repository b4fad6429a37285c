"""rf_bridge: the RoboFrame messaging bridge between ROS 2 and other systems.

One channel adapter per external system (``adapters/ros1``: a ROS 1 node of its own speaking
XML-RPC and TCPROS without rospy; ``adapters/team``: robot-to-robot over Zenoh), message
translators between their types (``translate/``), and a core that routes configured topics
with loop prevention, QoS mapping, throttling and statistics (``core/``). The ROS 2 side is
an efficient_comm component (``adapters/ros2``), so it runs standalone or composed.

Public: :class:`BridgeNode`, :func:`load_config`/:func:`parse_config`, the statistics
snapshot, the links' usage (:class:`LinkUsage`) and the exception tree; everything else
may change.
"""

from .adapters.ros2 import BridgeNode as BridgeNode
from .config import BridgeConfig as BridgeConfig
from .config import load_config as load_config
from .config import parse_config as parse_config
from .core.budget import LinkUsage as LinkUsage
from .core.stats import TopicStatsSnapshot as TopicStatsSnapshot
from .errors import ConfigError as ConfigError
from .errors import LinkError as LinkError
from .errors import ProtocolError as ProtocolError
from .errors import RfBridgeError as RfBridgeError
from .errors import TranslationError as TranslationError
