"""MuJoCo stands in for the Dynamixel servos of a kid-size humanoid (software in the loop).

So far: ``dynamixel`` (a Protocol 2.0 bus of emulated XM430 servos on a pseudo-terminal,
answering dynamixel-sdk unchanged). The MuJoCo robot and world, the simulator node, the
servo driver and the soccer demo pipeline come next.
"""
