"""rosbag2_layout: MCAP bags in the rosbag2 layout, the one owner of that format here.

robot_recorder (recording, playing) and team_clock (merging) both read and write bags
through this package, so both agree on every detail. Where things live (after rosbags'
``rosbag2/`` folder):

* ``writer``    :class:`BagWriter`: a bag directory of MCAP files (split by size or time,
  crash- and full-disk-safe) or one ``.mcap`` file; the :class:`FileSystem` seam;
* ``reader``    :class:`BagReader`: messages in log-time order, topics with their offered
  QoS, MCAP metadata records; files cut short are read up to their last complete chunk;
* ``metadata``  ``metadata.yaml`` (version 9) as typed dicts, offered QoS profiles;
* ``msgdefs``   message and service types by name and their complete ``ros2msg``
  definitions;
* ``cdr``       the exact CDR length of a message (what rclpy's serializer pads);
* ``livefile``  the MCAP file kept valid at every moment while it is written;
* ``recover``   a complete bag from one cut short; ``reindex`` (metadata.yaml again);
* ``errors``    :class:`Rosbag2Error` and its tree.

Everything public is re-exported here once.
"""

from .cdr import trim as trim
from .errors import BagConfigError as BagConfigError
from .errors import BagFormatError as BagFormatError
from .errors import BagNotFoundError as BagNotFoundError
from .errors import BagWriteError as BagWriteError
from .errors import Rosbag2Error as Rosbag2Error
from .errors import UnknownTypeError as UnknownTypeError
from .metadata import METADATA_VERSION as METADATA_VERSION
from .metadata import BagMetadata as BagMetadata
from .metadata import QosDict as QosDict
from .metadata import dump_qos as dump_qos
from .metadata import parse_qos as parse_qos
from .metadata import qos_dict as qos_dict
from .metadata import qos_profile as qos_profile
from .metadata import read_metadata as read_metadata
from .msgdefs import full_definition as full_definition
from .msgdefs import import_service as import_service
from .msgdefs import import_type as import_type
from .msgdefs import service_definitions as service_definitions
from .msgdefs import type_hash as type_hash
from .msgdefs import type_name as type_name
from .reader import BagMessage as BagMessage
from .reader import BagReader as BagReader
from .reader import TopicRecord as TopicRecord
from .reader import mcap_files as mcap_files
from .recover import recover as recover
from .recover import reindex as reindex
from .writer import BagWriter as BagWriter
from .writer import FileSystem as FileSystem
from .writer import TopicInfo as TopicInfo
