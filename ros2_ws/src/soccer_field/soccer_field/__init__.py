"""soccer_field: the field the robots play on, in one place.

The simulator builds its world on it (its MJCF is checked against it), the referee judges
goals and outs with it, the striker aims at its goal, and the debug GUI draws it. It is a
package of its own, below all of them and depending on nothing, so that a tool can read the
field without importing the simulator (and MuJoCo with it), and efficient_comm, which knows
nothing of soccer, stays a communication layer.
"""

from .errors import SoccerFieldError as SoccerFieldError
from .field import KIDSIZE as KIDSIZE
from .field import FieldDimensions as FieldDimensions
