"""MuJoCo stands in for the Dynamixel servos of a kid-size humanoid (software in the loop).

So far: ``dynamixel`` (a Protocol 2.0 bus of emulated XM430 servos on a pseudo-terminal,
answering dynamixel-sdk unchanged) and ``driver`` (the servo driver component: sync read,
sync write, joint states, diagnostics) and ``mujoco_plant`` with ``models/robot.xml`` (a
20-joint kid-size humanoid whose joints the emulated servos move). The field and ball, the
simulator node with camera and IMU, and the soccer demo pipeline come next.
"""
