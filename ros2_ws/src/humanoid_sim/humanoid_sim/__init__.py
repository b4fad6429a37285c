"""MuJoCo stands in for the Dynamixel servos of a kid-size humanoid (software in the loop).

So far: ``dynamixel`` (a Protocol 2.0 bus of emulated XM430 servos on a pseudo-terminal,
answering dynamixel-sdk unchanged) and ``driver`` (the servo driver component: sync read,
sync write, joint states, diagnostics). The MuJoCo robot and world (a ``Plant``), the
simulator node and the soccer demo pipeline come next.
"""
