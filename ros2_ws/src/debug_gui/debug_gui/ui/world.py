"""The world view (seed Fig. 5.6, 6.11): the field with every robot's beliefs and the truth.

Drawn as SVG, regenerated at the display rate: a field, a few robots and balls are a few
dozen elements, which the browser swaps faster than a canvas script could be sent, and SVG
elements carry test ids and titles (hover a robot for its pose and sources). Field metres
map to SVG units with y up, as the field frame has it.

Each robot has its colour (a team match's robots their team's shades): a filled disc with
a heading line for its pose belief, labelled with its name and role where it has one, a
small ring of the same colour for its ball estimate and a diamond for the ball its team
shares as it fused it; ground truth is drawn hollow and grey (pose) or black-ringed (ball);
the GUI's own fusion of the robots' balls is a dark star. Above the field, the referee's
game state and score, as the robots received them.

The drawing reaches the browser only when it changed (NiceGUI sends a changed property
only): robots standing still, a match in ``initial``, cost the browser nothing.
"""

from __future__ import annotations

import math
from html import escape

from nicegui import ui

from ..models.world import FIELD, FRESH_S, STALE_S, Game, RobotState, WorldModel
from .registry import ViewContext, register

POLL_S = 0.1
SCALE = 60.0  # SVG units per metre


def _pt(x: float, y: float) -> tuple[float, float]:
    """Field metres -> SVG coordinates (origin at the centre spot, y up)."""
    return round(x * SCALE, 1), round(-y * SCALE, 1)


def field_svg() -> str:
    """The KidSize field's lines (the static part of the drawing)."""
    f = FIELD
    hl, hw = f["length"] / 2, f["width"] / 2
    lines = []

    def rect(x0: float, y0: float, x1: float, y1: float) -> None:
        (ax, ay), (bx, by) = _pt(x0, y1), _pt(x1, y0)
        lines.append(f'<rect x="{ax}" y="{ay}" width="{bx - ax}" height="{by - ay}"/>')

    rect(-hl, -hw, hl, hw)
    for side in (-1, 1):
        for depth, width in ((f["goal_area_depth"], f["goal_area_width"]),
                             (f["penalty_area_depth"], f["penalty_area_width"])):
            inner = side * (hl - depth)
            rect(min(inner, side * hl), -width / 2, max(inner, side * hl), width / 2)
        mx, my = _pt(side * (hl - f["penalty_mark"]), 0)
        lines.append(f'<circle cx="{mx}" cy="{my}" r="3" fill="white"/>')
        gx, gy0 = _pt(side * hl, f["goal_width"] / 2)
        _, gy1 = _pt(side * hl, -f["goal_width"] / 2)
        depth = side * 0.4 * SCALE
        lines.append(f'<polyline points="{gx},{gy0} {gx + depth},{gy0} {gx + depth},{gy1} '
                     f'{gx},{gy1}" stroke="{"#ffd700" if side > 0 else "#00bfff"}" '
                     'stroke-width="5"/>')
    (cx, top), (_, bottom) = _pt(0, hw), _pt(0, -hw)
    lines.append(f'<line x1="{cx}" y1="{top}" x2="{cx}" y2="{bottom}"/>')
    lines.append(f'<circle cx="0" cy="0" r="{f["centre_circle"] / 2 * SCALE}"/>')
    return "".join(lines)


def _robot_svg(s: RobotState) -> str:
    key = escape(s.robot.key, quote=True)
    out = []
    if s.true_pose is not None:
        x, y = _pt(s.true_pose.x, s.true_pose.y)
        out.append(f'<circle data-testid="world-truth-{key}" cx="{x}" cy="{y}" r="9" '
                   'fill="none" stroke="#555" stroke-width="2" stroke-dasharray="3 2"/>')
    if s.true_ball is not None:
        x, y = _pt(*s.true_ball)
        out.append(f'<circle data-testid="world-true-ball-{key}" cx="{x}" cy="{y}" r="5" '
                   'fill="#ff8c00" stroke="black" stroke-width="1.5"/>')
    if s.pose is not None:
        x, y = _pt(s.pose.x, s.pose.y)
        hx, hy = _pt(s.pose.x + 0.3 * math.cos(s.pose.yaw), s.pose.y + 0.3 * math.sin(s.pose.yaw))
        title = (f"{s.robot.label}: x {s.pose.x:.2f} m, y {s.pose.y:.2f} m, "
                 f"heading {math.degrees(s.pose.yaw):.0f}° ({s.pose_source})"
                 + "".join(f", {v}" for v in (s.role, s.motion) if v))
        label = s.robot.name + (f" {s.role}" if s.role else "")
        out.append(
            f'<g data-testid="world-robot-{key}" data-x="{s.pose.x:.3f}" '
            f'data-y="{s.pose.y:.3f}" data-colour="{s.colour}" '
            f'data-source="{escape(s.pose_source, quote=True)}" '
            f'data-motion="{escape(s.motion, quote=True)}" '
            f'data-role="{escape(s.role, quote=True)}" data-team="{s.team}">'
            f'<title>{escape(title)}</title>'
            f'<circle cx="{x}" cy="{y}" r="8" fill="{s.colour}" stroke="white"/>'
            f'<line x1="{x}" y1="{y}" x2="{hx}" y2="{hy}" stroke="{s.colour}" '
            'stroke-width="3"/>'
            f'<text x="{x + 11}" y="{y - 9}" font-size="15" font-weight="bold" '
            f'fill="{s.colour}" stroke="white" stroke-width="3" paint-order="stroke">'
            f'{escape(label)}</text></g>')
    if s.ball is not None:
        x, y = _pt(*s.ball)
        out.append(f'<circle data-testid="world-ball-{key}" cx="{x}" cy="{y}" r="6" '
                   f'fill="none" stroke="{s.colour}" stroke-width="3" '
                   f'opacity="{ball_opacity(s.ball_age_s):.2f}"/>')
    if s.team_ball is not None:
        x, y = _pt(*s.team_ball)
        out.append(f'<path data-testid="world-team-ball-{key}" d="M{x},{y - 8} L{x + 8},{y} '
                   f'L{x},{y + 8} L{x - 8},{y} Z" fill="none" stroke="{s.colour}" '
                   f'stroke-width="2.5" opacity="{ball_opacity(s.team_ball_age_s):.2f}">'
                   f'<title>{escape(s.robot.name)}: the team ball as it fused it</title>'
                   '</path>')
    return "".join(out)


def ball_opacity(age_s: float | None) -> float:
    """Full while fresh, fading to a fifth until the estimate is too old to be drawn."""
    if age_s is None or age_s <= FRESH_S:
        return 1.0
    return max(0.2, 1.0 - 0.8 * (age_s - FRESH_S) / (STALE_S - FRESH_S))


def world_svg(states: list[RobotState], team_ball: tuple[float, float] | None) -> str:
    """The whole drawing: field, then truth and beliefs per robot, then the team ball."""
    hl = FIELD["length"] / 2 + FIELD["border"]
    hw = FIELD["width"] / 2 + FIELD["border"]
    parts = [
        f'<svg viewBox="{-hl * SCALE} {-hw * SCALE} {2 * hl * SCALE} {2 * hw * SCALE}" '
        'xmlns="http://www.w3.org/2000/svg" style="width:100%;max-width:48rem;'
        'background:#2e8b57">',
        f'<g fill="none" stroke="white" stroke-width="3">{field_svg()}</g>',
        *(_robot_svg(s) for s in states),
    ]
    if team_ball is not None:
        x, y = _pt(*team_ball)
        parts.append(
            f'<g data-testid="world-team-ball"><title>team ball (fused by the GUI)</title>'
            f'<path d="M{x},{y - 9} L{x + 3},{y - 3} L{x + 9},{y} L{x + 3},{y + 3} '
            f'L{x},{y + 9} L{x - 3},{y + 3} L{x - 9},{y} L{x - 3},{y - 3} Z" '
            'fill="#222"/></g>')
    parts.append("</svg>")
    return "".join(parts)


def legend(states: list[RobotState]) -> str:
    rows = []
    for s in states:
        where = ("no pose yet" if s.pose is None else
                 f"x {s.pose.x:.2f}, y {s.pose.y:.2f} ({s.pose_source})")
        ball = ("" if s.ball is None or s.ball_age_s is None else
                f"; ball {s.ball[0]:.2f}, {s.ball[1]:.2f} ({s.ball_age_s:.1f} s ago)")
        role = f" {s.role}" if s.role else ""
        motion = f" [{s.motion}]" if s.motion else ""
        rows.append(f'<span style="color:{s.colour}">●</span> '
                    f"{escape(s.robot.label)}{escape(role)}{escape(motion)}: "
                    f"{escape(where)}{escape(ball)}")
    return "<br>".join(rows) or "no robots"


def game_text(game: Game | None) -> str:
    """The referee's state and score above the field (as the robots received them)."""
    return "no game state (no referee heard)" if game is None else f"game: {game.text()}"


@register(kind="world", title="World", team=True, order=40)
def build(ctx: ViewContext) -> None:
    robots = [ctx.robot] if ctx.robot is not None else list(ctx.robots)
    model = WorldModel(ctx.source, robots)
    suffix = ctx.robot.key if ctx.robot is not None else "team"
    game = ui.label(game_text(None)).classes("text-subtitle2").props(
        f"data-testid=world-game-{suffix}")
    drawing = ui.html(world_svg([], None)).props(f"data-testid=world-{suffix}").classes("w-full")
    caption = ui.html("").classes("text-caption").props(f"data-testid=world-legend-{suffix}")

    def refresh() -> None:
        if not model.active:
            return
        states = model.states()
        # NiceGUI sends a property to the browser only when its value changed.
        drawing.content = world_svg(states, model.team_ball(states))
        caption.content = legend(states)
        game.text = game_text(model.game())

    ctx.follow(model, ui.timer(POLL_S, refresh, active=False))
