"""The bodies in motion: commands and the input buffer, force terms (steps 3 to 6 of the
article's algorithm), the model that sums them, and the fixed-step simulation (steps 7 and 8).

Data flows one way: the :class:`Simulation` composes the model, the contact solver
(:mod:`hecker_dynamics.contact`), the integrator (:mod:`hecker_dynamics.integrators`) and the
compiled kernel where it is built.
"""
from .commands import InputError, WrenchCommand
from .model import Model
from .simulation import BodyState, DivergenceError, Simulation, Snapshot

__all__ = ["InputError", "WrenchCommand", "Model", "BodyState", "DivergenceError",
           "Simulation", "Snapshot"]
