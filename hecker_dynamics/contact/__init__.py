"""Contacts: where shapes touch (``collision``, the narrow phase) and the impulses that
keep them apart (``solver``, in parts: ``detect``, ``warm``, ``islands``, ``solve``,
``sleep``, ``rows``), built only for scenes that declare walls or collisions; and
joints (``joints``): pins, sliders, welds, rods, ropes and gears, built only for scenes
that declare them."""
from .joints import (DistanceJoint, GearJoint, JointPass, JointSpec, PrismaticJoint,
                     RevoluteJoint, WeldJoint)
from .collision import CirclePart, Part, PolygonPart
from .detect import Contact
from .rows import Block, ContactRow
from .solver import ContactPass

__all__ = ["Block", "CirclePart", "Contact", "ContactPass", "ContactRow", "Part", "PolygonPart",
           "JointPass", "JointSpec", "RevoluteJoint", "PrismaticJoint", "WeldJoint",
           "DistanceJoint", "GearJoint"]
