"""The bodies in motion: the input buffer, force terms (steps 3 to 6 of the
article's algorithm), the model that sums them, and the fixed-step simulation (steps 7 and 8).

Data flows one way: the :class:`Simulation` composes the model, the contact solver
(:mod:`hecker_dynamics.contact`), the integrator (:mod:`hecker_dynamics.integrators`) and the
compiled kernel where it is built.
"""
from .model import Model
from .simulation import BodyState, DivergenceError, Simulation, Snapshot

__all__ = ["Model", "BodyState", "DivergenceError", "Simulation", "Snapshot"]
