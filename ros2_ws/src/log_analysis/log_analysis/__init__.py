"""log_analysis: offline analysis of team logs, with no GUI dependency.

A match leaves a merged log of every robot's recording on one time base (humanoid_sim's
match, team_clock's merge). This package reads it and finds what a person would look for:

* ``source``     :class:`TeamLog`: a log's messages by robot and topic, read by time window,
  decoded only when used (:class:`LogMessage`);
* ``events``     :class:`Event`, the :class:`EventGenerator` protocol,
  :func:`event_generator` (one of a function) and :func:`detect` (all generators in one
  pass; one that raises is reported and the others go on);
* ``generators`` the built-in generators (falls, ball lost, role oscillation, overrunning
  callbacks, ball disagreement, localization jumps, a silent team link, goals);
* ``registry``   generators by entry point (``log_analysis.event_generators``) or file;
* ``sidecar``    events in an MCAP beside the log with Foxglove's Event fields;
* ``video``      an external video: frames on the camera's clock, its calibration
  (:class:`~.video.Calibration`, the sidecar format humanoid_sim's match camera writes);
* ``sync``       the video's clock against the log's, fitted from the ball's motion or from
  anchors picked by hand (:class:`~.sync.VideoFit`);
* ``augment``    the video with every robot's beliefs drawn in, captions and a timeline;
* ``compare``    two variants of a component replayed on one log (A/B), with a report;
* ``cli``        the commands: ``events``, ``sync-video``, ``augment``, ``compare``;
* ``testing``    test doubles: a log from plain messages, a filmed ball on a known clock.
"""

from typing import TYPE_CHECKING

from efficient_comm.lazy import lazy_exports

#: Each public name and the module that defines it, imported on first use: a command (and
#: its ``--help``) loads what it runs, not video decoding, replays and rclpy all at once.
_EXPORTS: dict[str, str] = {
    "CompareError": ".errors",
    "GeneratorError": ".errors",
    "LogAnalysisError": ".errors",
    "LogSourceError": ".errors",
    "SyncError": ".errors",
    "Detection": ".events",
    "Event": ".events",
    "EventGenerator": ".events",
    "detect": ".events",
    "event_generator": ".events",
    "available_generators": ".registry",
    "generators_from_file": ".registry",
    "load_generators": ".registry",
    "read_events": ".sidecar",
    "sidecar_path": ".sidecar",
    "write_events": ".sidecar",
    "LogMessage": ".source",
    "TeamLog": ".source",
    "VideoFit": ".sync",
    "check_fit": ".sync",
    "fit_anchors": ".sync",
    "fit_video_clock": ".sync",
    "ExternalVideo": ".video",
    "VideoFrames": ".video",
}
__all__ = sorted(_EXPORTS)

if not TYPE_CHECKING:  # hidden from type checkers, which would take any name as valid
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
else:  # the same names for type checkers (tests/test_lazy_exports.py keeps both alike)
    from .errors import CompareError as CompareError
    from .errors import GeneratorError as GeneratorError
    from .errors import LogAnalysisError as LogAnalysisError
    from .errors import LogSourceError as LogSourceError
    from .errors import SyncError as SyncError
    from .events import Detection as Detection
    from .events import Event as Event
    from .events import EventGenerator as EventGenerator
    from .events import detect as detect
    from .events import event_generator as event_generator
    from .registry import available_generators as available_generators
    from .registry import generators_from_file as generators_from_file
    from .registry import load_generators as load_generators
    from .sidecar import read_events as read_events
    from .sidecar import sidecar_path as sidecar_path
    from .sidecar import write_events as write_events
    from .source import LogMessage as LogMessage
    from .source import TeamLog as TeamLog
    from .sync import VideoFit as VideoFit
    from .sync import check_fit as check_fit
    from .sync import fit_anchors as fit_anchors
    from .sync import fit_video_clock as fit_video_clock
    from .video import ExternalVideo as ExternalVideo
    from .video import VideoFrames as VideoFrames
