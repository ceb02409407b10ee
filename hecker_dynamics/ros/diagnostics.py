"""The node's diagnostic status (``diagnostic_msgs/DiagnosticStatus`` fields), without ROS."""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple, Optional

from ..dynamics.simulation import Simulation
from .fields import NS_PER_S

__all__ = ["DIAGNOSTIC_OK", "DIAGNOSTIC_WARN", "DIAGNOSTIC_ERROR", "DiagnosticFields",
           "diagnostic_fields", "diagnostics_due", "simulation_diagnostics"]

# diagnostic_msgs/msg/DiagnosticStatus levels (a ``byte`` field: rclpy wants
# ``bytes([level])``, rosbags an int).
DIAGNOSTIC_OK = 0
DIAGNOSTIC_WARN = 1
DIAGNOSTIC_ERROR = 2
#: Diagnostics are published at most this often, in sim time.
DIAGNOSTICS_PERIOD_NS = NS_PER_S
#: Name of the diagnostic status the node publishes.
DIAGNOSTIC_NAME = "hecker_dynamics: simulation"

class DiagnosticFields(NamedTuple):
    """``diagnostic_msgs/DiagnosticStatus``; ``values`` are (key, value) string pairs."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: tuple[tuple[str, str], ...]


def diagnostic_fields(level: int, message: str, values: Mapping[str, Any],
                      name: str = DIAGNOSTIC_NAME,
                      hardware_id: str = "dynamics_node") -> DiagnosticFields:
    """A diagnostic status; floats in ``values`` are written with 9 significant digits."""
    pairs = tuple((key, f"{value:.9g}" if isinstance(value, float) else str(value))
                  for key, value in values.items())
    return DiagnosticFields(level, name, message, hardware_id, pairs)


def diagnostics_due(last_ns: Optional[int], now_ns: int) -> bool:
    """Whether diagnostics are due at sim time ``now_ns`` (last published at ``last_ns``)."""
    return last_ns is None or now_ns - last_ns >= DIAGNOSTICS_PERIOD_NS


def simulation_diagnostics(sim: Simulation, *, halted: Optional[str], lag: int, substeps: int,
                           wall_ns: int, accepted: int, rejected: int,
                           hardware_id: str) -> DiagnosticFields:
    """The node's diagnostic status for ``sim`` after a tick of ``substeps`` steps.

    Level ERROR with the divergence message when ``halted``; WARN when the simulation lags
    the clock by ``lag`` ns; OK otherwise. ``wall_ns`` is the wall time the tick's steps
    took (zero where wall time must not show, as in an offline replay).
    """
    if halted is not None:
        level, message = DIAGNOSTIC_ERROR, halted
    elif lag:
        level, message = DIAGNOSTIC_WARN, f"{lag / NS_PER_S:.3f} s behind the clock"
    else:
        level, message = DIAGNOSTIC_OK, "running"
    return diagnostic_fields(level, message, {
        "sim_time": sim.time_ns / NS_PER_S,
        "start_time": sim.start_ns / NS_PER_S,
        "steps": sim.steps,
        "step": sim.step_ns / NS_PER_S,
        "substeps": substeps,
        "step_wall_time": wall_ns / substeps / NS_PER_S if substeps else 0.0,
        "energy": sim.snapshot().energy,
        "lag": lag / NS_PER_S,
        "commands_accepted": accepted,
        "commands_rejected": rejected,
    }, hardware_id=hardware_id)
