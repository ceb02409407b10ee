"""Contacts: where shapes touch (``collision``, the narrow phase) and the impulses that
keep them apart (``solver``), built only for scenes that declare walls or collisions; and
joints (``joints``): pins, sliders, welds, rods, ropes and gears, built only for scenes
that declare them."""
from .joints import (DistanceJoint, GearJoint, JointPass, JointSpec, PrismaticJoint,
                     RevoluteJoint, WeldJoint)
from .collision import CirclePart, Part, PolygonPart
from .solver import Block, Contact, ContactPass, ContactRow

__all__ = ["Block", "CirclePart", "Contact", "ContactPass", "ContactRow", "Part", "PolygonPart",
           "JointPass", "JointSpec", "RevoluteJoint", "PrismaticJoint", "WeldJoint",
           "DistanceJoint", "GearJoint"]
