"""The one exception root of rf_bridge and its tree.

::

    RfBridgeError
    ├── ConfigError          a bridge file or option is wrong (names the file and entry)
    ├── TranslationError     a message cannot be mapped between two systems' types
    │   ├── UnknownTypeError no definition (ROS 1) or no importable class (ROS 2) for a type
    │   └── OutOfRangeError  a value the other side's type cannot hold (dropped, counted)
    ├── ProtocolError        a peer sent bytes that break the wire protocol (TCPROS, XML-RPC)
    │   └── OversizeError    a frame larger than the configured limit
    └── LinkError            an external system cannot be reached (master down, peer gone)
        └── MasterRefusedError   (adapters.ros1.xmlrpc) it answered with an error code
"""

from __future__ import annotations


class RfBridgeError(Exception):
    """Root of every error rf_bridge raises on purpose."""


class ConfigError(RfBridgeError):
    pass


class TranslationError(RfBridgeError):
    pass


class UnknownTypeError(TranslationError):
    pass


class OutOfRangeError(TranslationError):
    pass


class ProtocolError(RfBridgeError):
    pass


class OversizeError(ProtocolError):
    pass


class LinkError(RfBridgeError):
    pass
