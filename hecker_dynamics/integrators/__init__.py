"""Integrators: the article's explicit Euler and its betters (semi-implicit Euler, Verlet,
RK4), the adaptive embedded pairs (``tableaux``), the implicit methods with colored
Jacobians (``coloring``), and ``auto``'s choice among them."""
from .methods import ADAPTIVE, METHODS, IntegrationError, Integrator, choose_method, make_integrator

__all__ = ["ADAPTIVE", "METHODS", "IntegrationError", "Integrator", "choose_method",
           "make_integrator"]
