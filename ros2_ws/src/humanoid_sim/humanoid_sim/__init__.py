"""MuJoCo stands in for the Dynamixel servos of a kid-size humanoid (software in the loop).

Layers, bottom up (ARCHITECTURE.md explains why the substitution is at the serial bus):

* ``dynamixel``: a Protocol 2.0 bus of emulated XM430 servos on a pseudo-terminal,
  answering dynamixel-sdk unchanged;
* ``mujoco_plant`` with ``models/``: the robot and the soccer field in MJCF, the joints the
  emulated servos move (``RobotPlant``, one robot's view by name prefix);
* ``world``: the team's world, the field with up to six robots, built with MjSpec;
* ``simulator`` and ``world_simulator`` (with ``pacing``, ``render``, ``sensors``): the
  components that step physics in real time or lockstep, serve the buses, and publish
  camera images, IMU and ground truth, for one robot and for a team in one world;
* ``driver``: the servo driver component, as it runs on the robot;
* ``soccer``: the robot's soccer pipeline (ball detection, ball model, behaviour, motion),
  a monitor scoring it against ground truth, and ``compose`` wiring everything together;
* ``demo``: the headless soccer demo with live statistics and a report.
"""
