"""robot_recorder: record on the robot off the callback path, control it remotely, play back.

Where things live:

* ``recorder``  the component: subscriptions, remote control, status;
* ``writer``    the writer thread (queue, serialization, ring buffer for snapshots);
* ``selection`` which topics, and throttle options;
* ``bag``       reading bags back (also files cut short by a crash), recovering them;
* ``player``    publishing a bag into a running system.

The bag format (MCAP in the rosbag2 layout, ``metadata.yaml``, message definitions) is
rosbag2_layout's; ``BagWriter`` and ``FileSystem`` are re-exported from there.

Everything public is re-exported here once.
"""

from rosbag2_layout import BagWriter as BagWriter
from rosbag2_layout import FileSystem as FileSystem

from .bag import BagMessage as BagMessage
from .bag import mcap_files as mcap_files
from .bag import read_messages as read_messages
from .bag import read_metadata_records as read_metadata_records
from .bag import recover as recover
from .bag import reindex as reindex
from .bag import unfinished_files as unfinished_files
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
