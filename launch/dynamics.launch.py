"""Launch dynamics_node with a scene: ros2 launch hecker_dynamics dynamics.launch.py scene:=sample.

``scene`` is the name of a scene shipped in the package's config/ directory (``sample``,
the default) or the path of a parameters file, resolved by the package's own rule
(:func:`hecker_dynamics.scene.load.scene_path`, which finds shipped scenes in
``share/hecker_dynamics/config`` through ``AMENT_PREFIX_PATH``), so an unknown name fails
here with the list of shipped scenes. ``use_sim_time`` makes the node follow /clock.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def _dynamics_node(context):
    from hecker_dynamics.scene.load import scene_path

    params_file = str(scene_path(LaunchConfiguration('scene').perform(context)).resolve())
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
