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
``referee`` judges goals from it and puts the ball back (neither is the robot's);
``team_referee`` runs a team game from ground truth as the GameController does
(``game_state``), ``game_control`` is the robot's side of it (what the striker may do in
each game state), and ``laws`` holds the rules both apply.
``team_comm`` is the robot's team layer (``TeamComm``): team messages out and in over the
team link (their format in ``team_message``), the ball fused with the teammates'
(``shared_ball``) and this robot's role (``roles``: ``Role``, with hysteresis).
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
  ``stop``, ``kick`` or ``fallen``; ``position`` or ``wait`` by the referee's order.
* ``game_state`` (soccer_interfaces/GameState, transient local): the referee's broadcast,
  when there is one (:mod:`.team_referee`); the striker obeys it (:mod:`.game_control`).
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
* ``team/messages`` (soccer_interfaces/TeamMessage): this robot's, at 2 Hz, and its
  teammates' (rf_bridge's team link carries the topic both ways); ``team_ball``
  (PoseWithCovarianceStamped, frame ``field``): the fused ball; ``role`` (String,
  transient local, on every change): ``striker``, ``supporter``, ``defender`` or
  ``goalie`` (``roles.Role``'s values). Input: ``localization/pose``
  (PoseWithCovarianceStamped, the team's field frame).
"""
