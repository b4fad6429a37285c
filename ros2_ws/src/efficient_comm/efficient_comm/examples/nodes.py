"""Console scripts running example components standalone (``ros2 run efficient_comm camera``)."""

from efficient_comm.examples.pipeline import Camera
from efficient_comm.standalone import standalone_main

camera = standalone_main(Camera, name="camera")
