"""The one-robot referee: goals and balls out of play, judged from ground truth; the ball put back.

A goal is the ball wholly over the goal line between the posts and under the crossbar
(Law 10: the whole ball past the line's outer edge); ``opponent`` goals are scored at
+x, the goal the robot attacks, ``own`` goals at -x. A ball wholly over a touch line or a
goal line elsewhere is out. After ``restart_s`` the ball is put back at rest, through the
simulator's ``place_ball`` topic: on the centre mark after a goal, just inside the field
where it left otherwise. The referee is not the robot's: only the simulation and the
report read it (the robot's software never sees ground truth). It judges the ball by the
same laws (:mod:`.laws`) as the team game's referee (:mod:`.team_referee`), which adds game
states, kick-offs, two teams' scores and set plays; this one keeps the one-robot demo's
game going without them.
"""

from __future__ import annotations

from geometry_msgs.msg import Point, PoseStamped

from efficient_comm.handle import NodeHandle
from soccer_field import KIDSIZE

from ..errors import SimConfigError
from .laws import Line, judge_ball

#: The field (soccer_field's KidSize, which ``models/soccer_field.xml`` is checked against):
#: half length and width, the goals' half width between the posts' inner faces and the
#: crossbar's lower edge (m).
HALF_LENGTH, HALF_WIDTH = KIDSIZE.half_length, KIDSIZE.half_width
GOAL_HALF_WIDTH, CROSSBAR = KIDSIZE.goal_width / 2, KIDSIZE.goal_height
#: How far inside the lines a ball out of play is put back (m).
INSIDE_M = 0.3


class Referee:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.restart_ns = round(node.declare_parameter("restart_s", 1.0) * 1e9)
        if self.restart_ns < 0:
            raise SimConfigError(f"need restart_s >= 0, got {self.restart_ns / 1e9}")
        self.goals = 0
        self.own_goals = 0
        self.outs = 0
        #: When the goals in the opponent goal were scored (ns since the referee started).
        self.goal_at_ns: list[int] = []
        self._start_ns = node.clock.now_ns()
        self._restart: tuple[int, Point] | None = None  # when and where the ball goes back
        self.place_pub = node.create_publisher(Point, "place_ball", qos=10)
        node.create_subscription(PoseStamped, "ground_truth/ball", self._on_ball, qos=10)

    def _on_ball(self, pose: PoseStamped) -> None:
        now = self.node.clock.now_ns()
        if self._restart is not None:
            when, where = self._restart
            if now >= when:
                self._restart = None
                self.place_pub.publish(where)
            return
        x, y, z = pose.pose.position.x, pose.pose.position.y, pose.pose.position.z
        crossing = judge_ball(x, y, z)
        if crossing is None:
            return
        if crossing.line is Line.GOAL:
            if crossing.x_side > 0:
                self.goals += 1
                self.goal_at_ns.append(now - self._start_ns)
                self.node.logger.info(f"GOAL ({self.goals})")
            else:
                self.own_goals += 1
                self.node.logger.info("own goal")
            where = Point()
        else:
            self.outs += 1
            where = Point(x=max(-HALF_LENGTH + INSIDE_M, min(HALF_LENGTH - INSIDE_M, x)),
                          y=max(-HALF_WIDTH + INSIDE_M, min(HALF_WIDTH - INSIDE_M, y)))
        self._restart = (now + self.restart_ns, where)
