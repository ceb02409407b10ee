"""Contact events as ``hecker_dynamics/msg/ContactEvent`` fields (no ROS import), for the
node to publish on :data:`~.names.CONTACT_EVENTS_TOPIC`."""
from __future__ import annotations

from typing import NamedTuple

from ..sensors.touch import TouchEvent
from .fields import Header, header

__all__ = ["ContactEventFields", "contact_event_fields"]


class ContactEventFields(NamedTuple):
    """``hecker_dynamics/msg/ContactEvent``."""

    header: Header
    event: int
    surface: str
    body_a: str
    body_b: str
    normal_impulse: float
    tangent_impulse: float


def contact_event_fields(frame_id: str, event: TouchEvent) -> ContactEventFields:
    """The message of ``event``, stamped with its instant in the fixed frame ``frame_id``."""
    return ContactEventFields(header(frame_id, event.stamp_ns), int(event.kind), event.surface,
                              event.body_a, event.body_b, event.normal_impulse,
                              event.tangent_impulse)
