"""team_clock: clock offsets between robots, and logs of several robots merged in one time.

Where things live (docs/TEAM_CLOCK.md explains the method):

* ``estimator`` offset and drift from NTP four-timestamp samples, with an error bound (no ROS);
* ``clocks``    the local-clock seam (``SkewedClock`` for simulated robots);
* ``sync``      the ``ClockSync`` component: exchanges, relaying through the team, publishing
  ``/team_clock/offset``;
* ``model``     ``OffsetModel``: a recorded robot's local time -> team reference time;
* ``bag``       reading logs (the format is rosbag2_layout's); ``merge`` aligning logs;
* ``testing``   a simulated lossy, delayed team network for tests.

Public here: the estimator, ``OffsetModel``, ``merge`` and its report, the errors. The
component is ``team_clock.sync.ClockSync`` (entry point ``clock_sync``), kept out of this
root so that reading and merging logs do not load the generated message modules.
"""

from .clocks import SkewedClock as SkewedClock
from .errors import LogFormatError as LogFormatError
from .errors import MergeError as MergeError
from .errors import NoEstimateError as NoEstimateError
from .errors import OtherRobotError as OtherRobotError
from .errors import TeamClockError as TeamClockError
from .estimator import Estimate as Estimate
from .estimator import OffsetEstimator as OffsetEstimator
from .estimator import Sample as Sample
from .merge import MergeReport as MergeReport
from .merge import RobotLog as RobotLog
from .merge import RobotReport as RobotReport
from .merge import merge as merge
from .model import OffsetModel as OffsetModel
