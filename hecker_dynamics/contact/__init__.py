"""Contacts: where shapes touch (``collision``, the narrow phase) and the impulses that
keep them apart (``solver``), built only for scenes that declare walls or collisions; and
the joint pass (``joints``), which holds the pins, sliders, welds, rods, ropes and gears
that a scene declares (:mod:`hecker_dynamics.scene.joints`), built only for scenes that
declare them."""
from .collision import CirclePart, Part, PolygonPart
from .joints import JointPass
from .solver import Block, Contact, ContactPass, ContactRow

__all__ = ["Block", "CirclePart", "Contact", "ContactPass", "ContactRow", "Part", "PolygonPart",
           "JointPass"]
