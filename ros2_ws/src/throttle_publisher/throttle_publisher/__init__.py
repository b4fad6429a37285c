"""Throttling at the publisher: each subscriber gets only the rate it asked for.

A throttled subscriber tells the publishers of its topic what it needs (maximum rate,
every n-th sample, pause) on an anti-parallel request topic; the publisher sends each
subscriber only that, and can skip computing samples nobody wants.

What is here so far: the options and their wire form (``options``), the per-subscriber
decision with the demand query (``gate``), and the request messages in
efficient_comm_interfaces (``ThrottleRequest``, ``ThrottleOption``). The publisher and
subscriber endpoints on the node handle come next.
"""

from .errors import InvalidOptionsError as InvalidOptionsError
from .errors import ThrottleError as ThrottleError
from .gate import Gate as Gate
from .options import ThrottleOptions as ThrottleOptions
from .options import from_wire as from_wire
from .options import options_from_msg as options_from_msg
from .options import request_msg as request_msg
