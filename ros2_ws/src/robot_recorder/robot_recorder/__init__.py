"""robot_recorder: record on the robot off the callback path, control it remotely, play back.

Where things live:

* ``recorder``  the component: subscriptions, remote control, status;
* ``writer``    the writer thread (queue, serialization, ring buffer for snapshots);
* ``storage``   bag directories of MCAP files in the rosbag2 layout, splitting, guards;
* ``msgdefs``   message types by name and their complete ``ros2msg`` definitions;
* ``selection`` which topics, and throttle options;
* ``bag``       reading bags back (also files cut short by a crash);
* ``player``    publishing a bag into a running system.

Everything public is re-exported here once.
"""

from .bag import BagMessage as BagMessage
from .bag import read_messages as read_messages
from .bag import recover as recover
from .errors import PlaybackError as PlaybackError
from .errors import RecorderConfigError as RecorderConfigError
from .errors import RecorderError as RecorderError
from .errors import StorageError as StorageError
from .errors import UnknownTypeError as UnknownTypeError
from .player import Player as Player
from .recorder import DEFAULT_CLOCK_TOPIC as DEFAULT_CLOCK_TOPIC
from .recorder import Recorder as Recorder
from .selection import TopicSelection as TopicSelection
from .selection import parse_selection as parse_selection
from .storage import BagWriter as BagWriter
from .storage import FileSystem as FileSystem
