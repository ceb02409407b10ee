"""Scenes: ROS 2 parameters files read, checked and turned into typed specs.

``parameters`` reads the flat dotted names of a parameters file; ``load`` builds the
:class:`Scene` (bodies, forces, walls, collisions, joints, inputs, integrator, outputs) and
refuses a bad file with a :class:`SceneError` that names the file and the parameter.
``commands`` holds the wrench commands a scene scripts and the node receives, ``joints`` the
joints' specs, ``names`` the node's and its services' names that a scene shares.
"""
from .commands import InputError, WrenchCommand
from .joints import (
                     DistanceJoint,
                     GearJoint,
                     JointSpec,
                     Motor,
                     PrismaticJoint,
                     RevoluteJoint,
                     RotarySpring,
                     WeldJoint,
)
from .load import (
                     DEFAULT_SCENE,
                     INTEGRATORS,
                     BodySpec,
                     Scene,
                     WrenchTopic,
                     load_scene,
                     scene_from_parameters,
                     scene_path,
                     shipped_scenes,
)
from .parameters import SceneError

__all__ = ["DEFAULT_SCENE", "INTEGRATORS", "BodySpec", "InputError", "WrenchCommand", "Scene",
           "SceneError", "WrenchTopic", "load_scene", "scene_from_parameters", "scene_path",
           "shipped_scenes", "DistanceJoint", "GearJoint", "JointSpec", "Motor", "PrismaticJoint",
           "RevoluteJoint", "RotarySpring", "WeldJoint"]
