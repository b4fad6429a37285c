"""The soccer robot's software, as composable components (camera to servos).

``vision`` finds the ball in camera images (OpenCV); ``world_model`` filters its bearing in
the robot's frame and places it on the ground; ``behaviour`` points the head at it (and
searches when it is lost); ``striker`` walks behind the ball lined up with the opponent
goal and asks for kicks (the body's behaviour);
``motion`` holds the standing pose; ``arbiter`` is the one writer of the servo driver's
joint commands, choosing among the motions (get-up > kick > walk > standing pose) with the
head goal on the neck; ``kick`` kicks the ball from standing (``kick_rig``: measured kicks);
``fall`` tells from the IMU whether the robot stands, is falling or lies on the ground;
``walk`` is the walk engine (``cmd_vel`` in, whole-body joint goals and odometry out), from
foot splines (``spline``) and the legs' analytic inverse kinematics (``leg_ik``);
``walk_rig`` is a robot that only walks, with a measured trial, for walking tests and bench;
``getup`` gets the robot up after a fall (keyframed motions from the front and the back),
``getup_rig`` measures a fall and get-up on the walking rig;
``landmarks`` finds goal posts and line points on the ground in camera images,
``localization`` places the robot on the field from them and odometry (a particle filter),
or stands in with noisy ground truth, and ``pose_error`` measures either against the truth;
``monitor`` measures what the pipeline achieves against the simulator's ground truth, and
``referee`` judges goals from it and puts the ball back (neither is the robot's).
``compose`` wires them, the simulator and the driver into one container.

Messages between them (all standard types, passed by reference when composed):

* ``ball/detection`` (PointStamped): x = yaw of the ball from the image centre (rad, left
  positive), y = pitch (rad, down positive), z = its angular radius (rad); the header is the
  image's.
* ``ball/estimate`` (PointStamped): x, y = filtered yaw and pitch of the ball from the
  torso's forward axis (rad), z = distance (m); stamped with the image it came from.
* ``ball/position`` (PointStamped, frame ``base_footprint``): where the ball lies on the
  ground, x forward and y left of the torso in the level frame (m).
* ``behaviour/state`` (String, transient local): the striker's ``search``, ``approach``,
  ``stop``, ``kick`` or ``fallen``.
* ``head/goal`` (JointState): neck_yaw and neck_pitch, stamped with the image it came from.
* ``fall/state`` (String, transient local): ``standing``, ``falling`` or ``fallen``.
* ``cmd_vel`` (Twist): the wanted walking velocity; ``odom`` (Odometry): the walk engine's
  odometry; ``motion/walk`` (JointState): the walk engine's whole-body goals.
* ``motion/<name>`` (JointState) and ``motion/<name>/active`` (Bool, transient local) for
  each motion (walk, kick, getup); ``motion/state`` (String, transient local): ``stand``,
  ``walk``, ``kick``, ``getup`` or ``fallen``; ``motion/kick/request`` (String): ``left`` or
  ``right``.
* ``landmarks/posts``, ``landmarks/lines`` (PointCloud2, frame ``base_footprint``): the
  goal posts' feet and points on field lines seen in an image, on the ground (m).
* ``localization/pose`` (PoseWithCovarianceStamped, frame ``field``) and
  ``localization/source`` (String, transient local: ``particle_filter`` or
  ``noisy_ground_truth``).
* ``motion/getup`` (JointState): the get-up's whole-body goals while it acts, and
  ``motion/getup/active`` (Bool, transient local, on every change): whether it owns the
  joints (from ``falling`` until the robot stands again).
"""
