"""MuJoCo stands in for the Dynamixel servos of a kid-size humanoid (software in the loop).

Layers, bottom up (ARCHITECTURE.md explains why the substitution is at the serial bus):

* ``dynamixel``: a Protocol 2.0 bus of emulated XM430 servos on a pseudo-terminal,
  answering dynamixel-sdk unchanged;
* ``mujoco_plant`` with ``models/``: the robot and the soccer field in MJCF, the joints the
  emulated servos move;
* ``simulator`` (with ``render``): the component that steps physics in real time or
  lockstep, serves the bus, and publishes camera images, IMU and ground truth;
* ``driver``: the servo driver component, as it runs on the robot;
* ``soccer``: the robot's soccer pipeline (ball detection, ball model, behaviour, motion),
  a monitor scoring it against ground truth, and ``compose`` wiring everything together;
* ``demo``: the headless soccer demo with live statistics and a report.
"""
