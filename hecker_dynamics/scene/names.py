"""The names a scene shares with the node: the node's name (a parameters file's top key)
and its services' names (a world event names the service that made it as its source).

They are plain strings, defined here once so that the scene reader needs nothing from
:mod:`hecker_dynamics.ros`; :mod:`hecker_dynamics.ros.names` lists them with the node's
topics and QoS.
"""
from __future__ import annotations

__all__ = ["NODE_NAME", "RESET_SERVICE", "PAUSE_SERVICE", "RESUME_SERVICE", "STEP_SERVICE",
           "SET_BODY_STATE_SERVICE", "SPAWN_BODY_SERVICE", "DELETE_BODY_SERVICE"]

#: The node's name: also the top key of a scene's parameters file.
NODE_NAME = "dynamics_node"

RESET_SERVICE = "reset"
PAUSE_SERVICE = "pause"
RESUME_SERVICE = "resume"
STEP_SERVICE = "step"
SET_BODY_STATE_SERVICE = "set_body_state"
SPAWN_BODY_SERVICE = "spawn_body"
DELETE_BODY_SERVICE = "delete_body"
