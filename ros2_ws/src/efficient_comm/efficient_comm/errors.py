"""Every error efficient_comm raises, under one root.

Catch :class:`EfficientCommError` to handle anything this package raises::

    EfficientCommError
    ├── NameResolutionError      an invalid topic/service/node name or remap rule
    ├── TopicTypeError           a topic used with two different message types in one process
    ├── UnknownTypeError         a type name that is malformed or not installed (LookupError)
    ├── ParameterError           undeclared, wrongly typed, read-only or rejected parameter
    ├── ComponentError           a component could not be created or loaded
    │   └── ConfigError          a container file or load request is malformed
    ├── ExecutorError            the executor was misused (spun from two threads, advance()
    │                            without a manual clock, a timer of an unloaded component)
    ├── DdsSetupError            the process cannot keep in-process and DDS delivery apart
    ├── LockstepError            a lockstep participant did not join or acknowledge a step in
    │                            time, or is gone (RuntimeError)
    ├── ServiceFailedError       an in-process service call failed (its callback raised)
    └── MessageMutatedError      a subscriber changed a message it received by reference
"""

from __future__ import annotations


class EfficientCommError(Exception):
    """Root of all efficient_comm errors."""


class NameResolutionError(EfficientCommError, ValueError):
    """A topic, service or node name (or a remap rule) is not a valid ROS 2 name."""


class TopicTypeError(EfficientCommError, TypeError):
    """One topic is used with two message types; ROS 2 would never connect them."""


class UnknownTypeError(EfficientCommError, LookupError):
    """A type name that is not ``pkg/msg/Name`` (or ``pkg/srv/Name``) or is not installed."""


class ParameterError(EfficientCommError, ValueError):
    """A parameter is undeclared, has the wrong type, is read-only or was rejected."""


class ComponentError(EfficientCommError):
    """A component could not be created, loaded or unloaded."""


class ConfigError(ComponentError, ValueError):
    """A container configuration (file or load request) is malformed.

    The message names the file and the entry so that a deployment can be fixed without
    reading a traceback.
    """


class ExecutorError(EfficientCommError, RuntimeError):
    """The executor was used in a way it does not support."""


class DdsSetupError(EfficientCommError, RuntimeError):
    """In-process endpoints are matched by DDS, so by-reference delivery would duplicate.

    Raised by a DDS-enabled container whose participant was created before
    :func:`efficient_comm.dds.prepare_process` could configure it (or under an RMW that
    cannot ignore local endpoints).
    """


class LockstepError(EfficientCommError, RuntimeError):
    """A lockstep participant never joined, did not acknowledge a step in time, or is gone.

    Raised by :class:`~efficient_comm.simtime.StepCoordinator` instead of waiting forever;
    :attr:`participants` names the culprits, the message says what each last acknowledged.
    """

    def __init__(self, message: str, *, participants: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.participants = participants


class MessageMutatedError(EfficientCommError):
    """A callback modified a message that other subscribers share by reference."""


class ServiceFailedError(EfficientCommError):
    """A service callback raised; an in-process caller's future holds this error.

    Set only for service types with no ``success`` field, which get no answer over DDS
    (see :mod:`efficient_comm._failures`); the cause is the callback's exception.
    """
