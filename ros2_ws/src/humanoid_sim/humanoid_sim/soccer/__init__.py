"""The soccer robot's software, as composable components (camera to servos).

``vision`` finds the ball in camera images (OpenCV); ``world_model`` filters its bearing in
the robot's frame; ``behaviour`` points the head at it (and searches when it is lost);
``motion`` turns stance and head goals into joint commands for the servo driver;
``fall`` tells from the IMU whether the robot stands, is falling or lies on the ground;
``walk`` is the walk engine (``cmd_vel`` in, whole-body joint goals and odometry out), from
foot splines (``spline``) and the legs' analytic inverse kinematics (``leg_ik``);
``walk_rig`` is a robot that only walks, with a measured trial, for walking tests and bench;
``getup`` gets the robot up after a fall (keyframed motions from the front and the back),
``getup_rig`` measures a fall and get-up on the walking rig;
``monitor`` measures what the pipeline achieves against the simulator's ground truth.
``compose`` wires them, the simulator and the driver into one container.

Messages between them (all standard types, passed by reference when composed):

* ``ball/detection`` (PointStamped): x = yaw of the ball from the image centre (rad, left
  positive), y = pitch (rad, down positive), z = its angular radius (rad); the header is the
  image's.
* ``ball/estimate`` (PointStamped): x, y = filtered yaw and pitch of the ball from the
  torso's forward axis (rad), z = distance (m); stamped with the image it came from.
* ``head/goal`` (JointState): neck_yaw and neck_pitch, stamped with the image it came from.
* ``fall/state`` (String, transient local): ``standing``, ``falling`` or ``fallen``.
* ``cmd_vel`` (Twist): the wanted walking velocity; ``odom`` (Odometry): the walk engine's
  odometry; ``motion/walk`` (JointState): the walk engine's whole-body goals.
* ``motion/getup`` (JointState): the get-up's whole-body goals while it acts, and
  ``motion/getup/active`` (Bool, transient local, on every change): whether it owns the
  joints (from ``falling`` until the robot stands again).
"""
