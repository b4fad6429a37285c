"""Throttling at the publisher: each subscriber gets only the rate it asked for.

A throttled subscriber tells the publishers of its topic what it needs (maximum rate,
every n-th sample, pause) on an anti-parallel request topic; the publisher sends each
subscriber only that, and can skip computing samples nobody wants.

Layers: ``options`` (what may be asked, and its wire form), ``gate`` (the per-subscriber
decision and the demand query), ``protocol`` (topics, QoS, timing: the specification),
``publisher`` and ``subscriber`` (the endpoints, written against efficient_comm's node
handle, so they work standalone, composed and under test alike).
"""

from .errors import InvalidOptionsError as InvalidOptionsError
from .errors import ThrottleError as ThrottleError
from .gate import Gate as Gate
from .options import ThrottleOptions as ThrottleOptions
from .options import from_wire as from_wire
from .options import options_from_msg as options_from_msg
from .options import request_msg as request_msg
from .publisher import ThrottledPublisher as ThrottledPublisher
from .subscriber import ThrottledSubscription as ThrottledSubscription
