"""How long the commands listen for the graph; a module of its own because the command line
(``--spin-time``'s default) needs it before anything imports rclpy: ``ros2 run`` and
``ros2 pkg`` never do."""

#: A running Fast DDS participant answers a newcomer only with its next periodic announcement
#: (every 3 s), so a command that lists the whole graph listens at least this long ...
ANNOUNCE_S = 3.5
#: ... and then until the graph has not changed for this long and every endpoint seen has
#: its node's name (names come in a second step of discovery) ...
QUIET_S = 0.5
#: ... or until this long, whatever the graph still does (nodes coming and going).
SETTLE_MAX_S = 6.0
#: How long a command waits for the node, topic or service it was asked about.
WAIT_S = 10.0
