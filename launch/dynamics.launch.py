"""Launch dynamics_node with a scene: ros2 launch hecker_dynamics dynamics.launch.py scene:=sample.

``scene`` is the name of a scene shipped in the package's config/ directory (``sample``,
the default) or the path of a parameters file; ``use_sim_time`` makes the node follow
/clock.
"""
import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


def _is_path(scene: str) -> bool:
    """A scene argument that names a file rather than a shipped scene (as the core decides)."""
    return scene.endswith(('.yaml', '.yml')) or os.sep in scene or os.path.exists(scene)


def _dynamics_node(context):
    scene = LaunchConfiguration('scene').perform(context)
    if _is_path(scene):
        params_file = os.path.abspath(scene)
    else:
        share = FindPackageShare('hecker_dynamics').perform(context)
        params_file = os.path.join(share, 'config', f'{scene}.yaml')
    return [Node(
        package='hecker_dynamics',
        executable='dynamics_node',
        name='dynamics_node',
        output='screen',
        parameters=[
            params_file,
            {'use_sim_time': ParameterValue(LaunchConfiguration('use_sim_time'),
                                            value_type=bool)},
        ],
    )]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument(
            'scene', default_value='sample',
            description='shipped scene name (config/<name>.yaml) or path to a parameters file'),
        DeclareLaunchArgument(
            'use_sim_time', default_value='false', choices=['true', 'false'],
            description='follow /clock instead of the system clock'),
        OpaqueFunction(function=_dynamics_node),
    ])
