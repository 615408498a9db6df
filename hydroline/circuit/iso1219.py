"""Graphic symbols of ISO 1219-1 (fluid power, graphic symbols) drawn with Matplotlib, for
the circuit schematic (:mod:`hydroline.circuit.schematic`).

Each symbol is drawn by a function of a :class:`Pen` -- a Matplotlib axes with a placement
(position, mirror, quarter turns) -- in the symbol's own coordinates, one unit about the
side of a valve envelope; it returns the symbol's connection points there. The pen records
the extent of everything drawn, the symbol's bounding box. The shapes follow ISO 1219-1:2012:
a pump is a circle with a filled triangle pointing out of its outlet; a pressure source the
same without a drive shaft; a tank an open-topped rectangle the line enters; a relief valve a
square envelope with the flow arrow offset from the ports (normally closed), its spring and
dashed pilot line from the inlet; a check valve a ball on a seat; an accumulator a capsule
with its separating piston and the gas charge's filled triangle; a fixed restriction two arcs
narrowing the line; a flexible hose an arc; a junction a dot; the servovalve three envelopes
(flow paths straight, blocked, crossed) between the two parallel lines of a continuously
positioned valve, with its torque motor and centring spring; the cylinder double acting with
a rod through both end caps.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["Pen", "SYMBOLS", "LINE_WIDTH"]

#: Line width of symbols and working lines, [points].
LINE_WIDTH = 1.1


class Pen:
    """Draws in a symbol's own coordinates ``(u, v)`` onto Matplotlib axes, placed at
    ``(x, y)``, mirrored in u when ``mirror``, turned by ``quarter_turns`` x 90 deg
    counter-clockwise, and records the drawn extent (:attr:`box`).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The axes, in drawing units (equal aspect).
    x, y : float
        Where the symbol's origin is placed, [drawing units].
    mirror : bool
        Mirror the symbol in its u axis (a flow from right to left).
    quarter_turns : int
        Quarter turns counter-clockwise, [-].
    color : str
        Line colour.
    """

    def __init__(self, ax, x: float, y: float, mirror: bool = False, quarter_turns: int = 0,
                 color: str = "k"):
        self.ax, self.x, self.y = ax, float(x), float(y)
        self.mirror, self.turns, self.color = mirror, quarter_turns % 4, color
        self.extent = [math.inf, math.inf, -math.inf, -math.inf]

    def point(self, u: float, v: float) -> tuple:
        """Where a point of the symbol lies in the drawing.

        Parameters
        ----------
        u, v : float
            The point in the symbol's coordinates, [drawing units].

        Returns
        -------
        tuple
            (x, y), [drawing units].
        """
        if self.mirror:
            u = -u
        for _ in range(self.turns):
            u, v = -v, u
        return self.x + u, self.y + v

    def _grow(self, xs, ys):
        e = self.extent
        e[0], e[1] = min(e[0], min(xs)), min(e[1], min(ys))
        e[2], e[3] = max(e[2], max(xs)), max(e[3], max(ys))

    def line(self, points, **style):
        """A polyline through ``points`` (symbol coordinates).

        Parameters
        ----------
        points : list of tuple
            (u, v) of each vertex, [drawing units].
        style : dict
            Matplotlib line properties (``lw``, ``ls``, ...).
        """
        xy = [self.point(u, v) for u, v in points]
        xs, ys = [p[0] for p in xy], [p[1] for p in xy]
        self._grow(xs, ys)
        self.ax.plot(xs, ys, color=style.pop("color", self.color),
                     lw=style.pop("lw", LINE_WIDTH), solid_capstyle="butt", **style)

    def polygon(self, points, fill: bool = False, **style):
        """A closed polygon (filled in the pen's colour when ``fill``).

        Parameters
        ----------
        points : list of tuple
            (u, v) of each vertex, [drawing units].
        fill : bool
            Filled (a triangle of ISO 1219: hydraulic energy) or outlined.
        style : dict
            Matplotlib patch properties.
        """
        from matplotlib.patches import Polygon

        xy = [self.point(u, v) for u, v in points]
        self._grow([p[0] for p in xy], [p[1] for p in xy])
        self.ax.add_patch(Polygon(xy, closed=True, fill=fill, lw=style.pop("lw", LINE_WIDTH),
                                  edgecolor=self.color, facecolor=self.color if fill else "none",
                                  **style))

    def circle(self, u: float, v: float, r: float, fill: bool = False):
        """A circle of radius ``r`` about ``(u, v)``.

        Parameters
        ----------
        u, v : float
            Centre, [drawing units].
        r : float
            Radius, [drawing units].
        fill : bool
            Filled (a junction dot) or outlined.
        """
        from matplotlib.patches import Circle

        x, y = self.point(u, v)
        self._grow([x - r, x + r], [y - r, y + r])
        self.ax.add_patch(Circle((x, y), r, fill=fill, lw=LINE_WIDTH, edgecolor=self.color,
                                 facecolor=self.color if fill else "none", zorder=3))

    def arc(self, u: float, v: float, r: float, a0: float, a1: float, **style):
        """An arc of radius ``r`` about ``(u, v)`` from angle ``a0`` to ``a1``.

        Parameters
        ----------
        u, v : float
            Centre, [drawing units].
        r : float
            Radius, [drawing units].
        a0, a1 : float
            Start and end angles in the symbol's coordinates, [deg].
        style : dict
            Matplotlib line properties.
        """
        a = np.radians(np.linspace(a0, a1, 25))
        self.line(list(zip(u + r * np.cos(a), v + r * np.sin(a))), **style)

    def zigzag(self, start, end, teeth: int = 4, width: float = 0.12):
        """A spring: a zigzag from ``start`` to ``end``.

        Parameters
        ----------
        start, end : tuple
            (u, v) of its ends, [drawing units].
        teeth : int
            Teeth, [-].
        width : float
            Half the zigzag's width, [drawing units].
        """
        (u0, v0), (u1, v1) = start, end
        n = 2 * teeth
        length = math.hypot(u1 - u0, v1 - v0)
        du, dv = (u1 - u0) / length, (v1 - v0) / length
        pts = [(u0, v0)]
        for k in range(1, n):
            f = k / n
            s = width * (1 if k % 2 else -1)
            pts.append((u0 + f * (u1 - u0) - s * dv, v0 + f * (v1 - v0) + s * du))
        pts.append((u1, v1))
        self.line(pts, lw=0.8)

    def arrow(self, start, end, head: float = 0.12, **style):
        """A flow-path arrow (a line with a filled head at ``end``).

        Parameters
        ----------
        start, end : tuple
            (u, v) of its tail and tip, [drawing units].
        head : float
            Length of the head, [drawing units].
        style : dict
            Matplotlib line properties.
        """
        (u0, v0), (u1, v1) = start, end
        length = math.hypot(u1 - u0, v1 - v0)
        du, dv = (u1 - u0) / length, (v1 - v0) / length
        base = (u1 - head * du, v1 - head * dv)
        self.line([start, base], lw=style.pop("lw", 0.9), **style)
        w = 0.45 * head
        self.polygon([(u1, v1), (base[0] - w * dv, base[1] + w * du),
                      (base[0] + w * dv, base[1] - w * du)], fill=True, lw=0.5)

    def text(self, u: float, v: float, s: str, **style):
        """Text at a point of the symbol (a port letter), upright whatever the placement.

        Parameters
        ----------
        u, v : float
            Where, [drawing units].
        s : str
            The text.
        style : dict
            Matplotlib text properties.
        """
        x, y = self.point(u, v)
        self.ax.text(x, y, s, fontsize=style.pop("fontsize", 6), ha=style.pop("ha", "center"),
                     va=style.pop("va", "center"), color=style.pop("color", self.color), **style)

    @property
    def box(self) -> tuple:
        """The extent drawn so far: (x0, y0, x1, y1), [drawing units]."""
        return tuple(self.extent)


# ---- symbols: each returns its connection points {name: (u, v)} -------------------------

def hose(pen: Pen, length: float = 2.6) -> dict:
    """A flexible hose: an arc between its two ends (ISO 1219-1 flexible line).

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).
    length : float
        Distance between its ends, [drawing units].

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    h = 0.28 * length / 2.6                     # how far the hose bulges up
    r = (length / 2) ** 2 / (2 * h) + h / 2       # radius of the arc through ends and crest
    a = math.degrees(math.atan2(length / 2, r - h))
    pen.arc(0.0, h - r, r, 90 - a, 90 + a)
    return {"a": (-length / 2, 0.0), "b": (length / 2, 0.0)}


def restriction(pen: Pen) -> dict:
    """A fixed restriction (throttle): the line narrowed between two arcs.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.line([(-0.6, 0.0), (0.6, 0.0)])
    for side in (1, -1):   # each arc bowing toward the line
        pen.arc(0.0, side * 0.5, 0.4, -90 * side - 50, -90 * side + 50)
    return {"a": (-0.6, 0.0), "b": (0.6, 0.0)}


def check_valve(pen: Pen) -> dict:
    """A check valve: a ball on a conical seat; free flow from ``a`` (the seat's apex side)
    to ``b``.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.line([(-0.6, 0.0), (-0.22, 0.0)])
    pen.line([(0.2, 0.26), (-0.22, 0.0), (0.2, -0.26)])
    pen.circle(0.08, 0.0, 0.15)
    pen.line([(0.23, 0.0), (0.6, 0.0)])
    return {"a": (-0.6, 0.0), "b": (0.6, 0.0)}


def relief_valve(pen: Pen) -> dict:
    """A pressure-relief valve, normally closed: the flow arrow offset from the ports in a
    square envelope, an adjustable spring on one side and the pilot line (dashed) from the
    inlet ``a`` to the other.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    s = 0.4
    pen.polygon([(-s, -s), (s, -s), (s, s), (-s, s)])
    pen.line([(-0.75, 0.0), (-s, 0.0)])
    pen.line([(s, 0.0), (0.75, 0.0)])
    pen.arrow((-s + 0.08, 0.2), (s - 0.08, 0.2))
    pen.zigzag((0.0, s), (0.0, s + 0.38), teeth=3)
    pen.line([(-0.12, s + 0.06), (0.12, s + 0.32)], lw=0.6)   # adjustable
    pen.line([(-0.6, 0.0), (-0.6, -s - 0.15), (0.0, -s - 0.15), (0.0, -s)], lw=0.7, ls=(0, (3, 2)))
    return {"a": (-0.75, 0.0), "b": (0.75, 0.0)}


def pump(pen: Pen) -> dict:
    """A fixed-displacement pump: a circle, the filled triangle pointing out of the outlet
    ``b``, the drive shaft below.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    r = 0.38
    pen.circle(0.0, 0.0, r)
    pen.polygon([(r, 0.0), (r - 0.3, 0.17), (r - 0.3, -0.17)], fill=True)
    pen.line([(-0.7, 0.0), (-r, 0.0)])
    pen.line([(r, 0.0), (0.7, 0.0)])
    pen.line([(-0.04, -r), (-0.04, -r - 0.28)], lw=0.9)
    pen.line([(0.04, -r), (0.04, -r - 0.28)], lw=0.9)
    return {"a": (-0.7, 0.0), "b": (0.7, 0.0)}


def pressure_source(pen: Pen) -> dict:
    """A hydraulic pressure source (power unit): a circle with the filled triangle pointing
    out of its port ``b``.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    r = 0.38
    pen.circle(0.0, 0.0, r)
    pen.polygon([(r, 0.0), (r - 0.3, 0.17), (r - 0.3, -0.17)], fill=True)
    pen.line([(r, 0.0), (0.7, 0.0)])
    return {"b": (0.7, 0.0)}


def tank(pen: Pen) -> dict:
    """A tank (reservoir): an open-topped rectangle the line ``b`` enters from above and
    ends in, below the oil level.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.line([(-0.38, -0.2), (-0.38, -0.62), (0.38, -0.62), (0.38, -0.2)])
    pen.line([(0.6, 0.0), (0.0, 0.0), (0.0, -0.5)])
    return {"b": (0.6, 0.0)}


def accumulator(pen: Pen) -> dict:
    """A gas-loaded piston accumulator, upright on its port ``a``: a capsule, the piston
    across it and the gas charge's filled triangle at the top.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    w, bottom, top = 0.28, 0.25, 1.35
    pen.line([(0.0, 0.0), (0.0, bottom)])
    pen.arc(0.0, bottom + w, w, 180, 360)
    pen.arc(0.0, top - w, w, 0, 180)
    pen.line([(-w, bottom + w), (-w, top - w)])
    pen.line([(w, bottom + w), (w, top - w)])
    mid = 0.5 * (bottom + top)
    pen.line([(-w, mid), (w, mid)], lw=1.6)
    pen.line([(-w, mid + 0.08), (w, mid + 0.08)], lw=0.8)
    pen.polygon([(0.0, top - 0.12), (-0.1, top - 0.3), (0.1, top - 0.3)], fill=True)
    return {"a": (0.0, 0.0)}


def volume(pen: Pen) -> dict:
    """A lumped oil volume, upright on its port ``a``: a closed vessel.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.line([(0.0, 0.0), (0.0, 0.25)])
    pen.polygon([(-0.4, 0.25), (0.4, 0.25), (0.4, 0.85), (-0.4, 0.85)])
    pen.text(0.0, 0.55, "V", fontsize=7)
    return {"a": (0.0, 0.0)}


def junction(pen: Pen) -> dict:
    """A junction of lines: a dot.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.circle(0.0, 0.0, 0.09, fill=True)
    return {"a": (0.0, 0.0)}


def servovalve(pen: Pen) -> dict:
    """A 4/3 servovalve: three envelopes (left: P to A and B to T; middle: closed; right:
    P to B and A to T) between the two parallel lines of a continuously positioned valve,
    the centring spring at the left and the torque motor at the right. Ports P, T below the
    middle envelope, A, B above it.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    w, h = 1.0, 0.8
    for k in (-1, 0, 1):
        pen.polygon([(k * w - w / 2, -h / 2), (k * w + w / 2, -h / 2),
                     (k * w + w / 2, h / 2), (k * w - w / 2, h / 2)])
    for v in (-h / 2 - 0.1, h / 2 + 0.1):
        pen.line([(-1.5 * w, v), (1.5 * w, v)], lw=0.8)
    a_, b_ = -0.25, 0.25          # port positions in an envelope
    # left envelope: straight paths P -> A, B -> T
    pen.arrow((-w + a_, -h / 2 + 0.05), (-w + a_, h / 2 - 0.05))
    pen.arrow((-w + b_, h / 2 - 0.05), (-w + b_, -h / 2 + 0.05))
    # right envelope: crossed paths P -> B, A -> T
    pen.arrow((w + a_, -h / 2 + 0.05), (w + b_, h / 2 - 0.05))
    pen.arrow((w + a_, h / 2 - 0.05), (w + b_, -h / 2 + 0.05))
    # middle envelope: every port closed
    for u, v, d in ((a_, h / 2, -1), (b_, h / 2, -1), (a_, -h / 2, 1), (b_, -h / 2, 1)):
        pen.line([(u, v), (u, v + d * 0.16)], lw=0.9)
        pen.line([(u - 0.07, v + d * 0.16), (u + 0.07, v + d * 0.16)], lw=0.9)
    for u, v, s in ((a_, -h / 2 - 0.22, "P"), (b_, -h / 2 - 0.22, "T"),
                    (a_, h / 2 + 0.22, "A"), (b_, h / 2 + 0.22, "B")):
        pen.text(u - 0.12, v, s, fontsize=5.5)
    # centring spring (left) and torque motor (right): an envelope with the variable arrow
    pen.zigzag((-1.5 * w, 0.0), (-1.5 * w - 0.4, 0.0), teeth=3)
    m0 = 1.5 * w
    pen.polygon([(m0, -0.25), (m0 + 0.4, -0.25), (m0 + 0.4, 0.25), (m0, 0.25)])
    pen.line([(m0 + 0.06, -0.2), (m0 + 0.34, 0.2)], lw=0.7)
    pen.line([(m0 + 0.4, 0.0), (m0 + 0.55, 0.0)], lw=0.7)
    return {"supply": (a_, -h / 2), "return": (b_, -h / 2), "bottom": (a_, h / 2),
            "top": (b_, h / 2), "motor": (m0 + 0.55, 0.0)}


def cylinder(pen: Pen) -> dict:
    """A double-acting cylinder with a rod through both end caps: the bottom chamber's port
    at the left, the top chamber's at the right, below; the rod's right end ``rod``.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    L, H = 2.4, 0.7
    pen.polygon([(-L / 2, -H / 2), (L / 2, -H / 2), (L / 2, H / 2), (-L / 2, H / 2)])
    pen.line([(0.0, -H / 2), (0.0, H / 2)], lw=2.2)
    pen.line([(-L / 2 - 0.7, 0.0), (L / 2 + 0.7, 0.0)], lw=2.0)
    return {"bottom": (-0.9, -H / 2), "top": (0.9, -H / 2), "rod": (L / 2 + 0.7, 0.0),
            "rod_left": (-L / 2 - 0.7, 0.0)}


def load(pen: Pen) -> dict:
    """The load on the rod: a mass, with the specimen's spring to the frame.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.polygon([(0.0, -0.35), (0.7, -0.35), (0.7, 0.35), (0.0, 0.35)])
    pen.text(0.35, 0.0, "m", fontsize=7)
    pen.zigzag((0.7, 0.0), (1.2, 0.0), teeth=3)
    pen.line([(1.2, -0.3), (1.2, 0.3)], lw=1.4)
    for k in range(4):
        v = -0.3 + 0.2 * k
        pen.line([(1.2, v), (1.32, v + 0.12)], lw=0.6)
    return {"a": (0.0, 0.0)}


def friction(pen: Pen) -> dict:
    """Friction on the piston rod: a hatched guide the rod ``a`` runs through (no ISO 1219
    symbol; drawn as a gland).

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.polygon([(-0.55, -0.2), (0.0, -0.2), (0.0, 0.2), (-0.55, 0.2)])
    for k in range(4):
        u = -0.5 + 0.13 * k
        pen.line([(u, -0.2), (u + 0.1, 0.2)], lw=0.5)
    pen.line([(-0.55, 0.0), (0.0, 0.0)], lw=2.0)
    return {"a": (0.0, 0.0)}


def controller(pen: Pen) -> dict:
    """A controller: a signal-processing box (electrical, not ISO 1219 fluid power).

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.polygon([(-0.7, -0.3), (0.7, -0.3), (0.7, 0.3), (-0.7, 0.3)])
    return {"out": (-0.7, 0.0), "feedback": (0.0, 0.3), "reference": (0.7, 0.0)}


def command(pen: Pen) -> dict:
    """A command signal source: a small box with its waveform named.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.polygon([(-0.5, -0.22), (0.5, -0.22), (0.5, 0.22), (-0.5, 0.22)])
    return {"out": (-0.5, 0.0)}


def component_box(pen: Pen) -> dict:
    """A component without a symbol of its own (a user's type): a box.

    Parameters
    ----------
    pen : Pen
        Where the symbol goes (position, mirror, turns).

    Returns
    -------
    dict
        Its connection points, name -> (u, v) in its own coordinates, [drawing units].
    """
    pen.polygon([(-0.6, -0.3), (0.6, -0.3), (0.6, 0.3), (-0.6, 0.3)])
    return {"a": (-0.6, 0.0), "b": (0.6, 0.0)}


#: Symbol name -> drawing function.
SYMBOLS = {"hose": hose, "restriction": restriction, "check_valve": check_valve,
           "relief_valve": relief_valve, "pump": pump, "pressure_source": pressure_source,
           "tank": tank, "accumulator": accumulator, "volume": volume, "junction": junction,
           "servovalve": servovalve, "cylinder": cylinder, "load": load, "friction": friction,
           "controller": controller, "command": command, "box": component_box}
