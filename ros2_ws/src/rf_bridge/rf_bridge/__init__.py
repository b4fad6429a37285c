"""Bridge that passes messages between RoboFrame-style components and ROS topics.

Will hold the bridge nodes and their configuration (thesis section 4.5); later work fills it in.
"""
