"""Robot-side debug probes: what a debugging view needs from the robot, free while unwatched.

* ``drawing``     :class:`DebugDrawing`, debug drawings over a camera image in layers
                  (visualization_msgs/ImageMarker in efficient_comm_interfaces/ImageMarkerArray),
                  and :func:`read_drawing`, the reader of the same format;
* ``compressor``  :class:`JpegCompressor`, the camera as JPEG, encoded only on demand.

Both publish through throttle_publisher, so a viewer asks for the rate it displays and
nothing is computed while nobody looks. Depends on efficient_comm, throttle_publisher and
ROS messages only (no GUI toolkit): it runs on the robot.
"""

from .compressor import JPEG_QUALITY as JPEG_QUALITY
from .compressor import JpegCompressor as JpegCompressor
from .drawing import BLUE as BLUE
from .drawing import CYAN as CYAN
from .drawing import GREEN as GREEN
from .drawing import MAGENTA as MAGENTA
from .drawing import RED as RED
from .drawing import WHITE as WHITE
from .drawing import YELLOW as YELLOW
from .drawing import Color as Color
from .drawing import DebugDrawing as DebugDrawing
from .drawing import Drawing as Drawing
from .drawing import Shape as Shape
from .drawing import layer_names as layer_names
from .drawing import read_drawing as read_drawing
from .errors import DebugProbesError as DebugProbesError
from .errors import DrawingError as DrawingError
from .errors import ProbeConfigError as ProbeConfigError
