"""Contacts: where shapes touch (``collision``, the narrow phase) and the impulses that
keep them apart (``solver``), built only for scenes that declare walls or collisions."""
from .solver import Contact, ContactPass, ContactRow

__all__ = ["Contact", "ContactPass", "ContactRow"]
