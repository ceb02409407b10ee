"""Launch dynamics_node with a scene: ros2 launch hecker_dynamics dynamics.launch.py scene:=sample.

``scene`` is the name of a scene shipped in the package's config/ directory (``sample``,
the default) or the path of a parameters file, resolved by the package's own rule
(:func:`hecker_dynamics.scene.load.scene_path`, which finds shipped scenes in
``share/hecker_dynamics/config`` through ``AMENT_PREFIX_PATH``), so an unknown name fails
here with the list of shipped scenes. ``use_sim_time`` makes the node follow /clock.

``rviz:=true`` also starts RViz2 with the package's view (rviz/hecker_dynamics.rviz: TF and
the shape markers) in the scene's fixed frame, and turns the node's markers on;
``markers:=true|false`` sets them either way (``auto``: on with RViz, else as the scene says).
Where RViz2 is not installed (a headless machine), the node starts alone and one log line
says why there is no RViz.
"""
import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

RVIZ_CONFIG = 'rviz/hecker_dynamics.rviz'


def _markers_on(rviz: bool, markers: str):
    """The ``publish.markers`` override: None keeps the scene's setting."""
    if markers == 'auto':
        return True if rviz else None
    return markers == 'true'


def _rviz_missing():
    """Why RViz2 cannot start here, or None: its package and executable looked up as
    launch_ros's Node looks an executable up (the package's ament prefix, then
    lib/<package>/<executable>), so a missing one is found before the launch would fail."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        prefix = get_package_prefix('rviz2')
    except PackageNotFoundError:
        return 'the rviz2 package is not installed (apt install ros-jazzy-rviz2)'
    executable = os.path.join(prefix, 'lib', 'rviz2', 'rviz2')
    if not os.access(executable, os.X_OK):
        return f'the rviz2 package has no executable {executable}'
    return None


def _dynamics_node(context):
    from ament_index_python.packages import get_package_share_directory

    from hecker_dynamics.scene.load import load_scene, scene_path

    params_file = str(scene_path(LaunchConfiguration('scene').perform(context)).resolve())
    rviz = LaunchConfiguration('rviz').perform(context) == 'true'
    overrides = {'use_sim_time': ParameterValue(LaunchConfiguration('use_sim_time'),
                                                value_type=bool)}
    markers = _markers_on(rviz, LaunchConfiguration('markers').perform(context))
    if markers is not None:
        overrides['publish.markers'] = markers
    actions = [Node(
        package='hecker_dynamics',
        executable='dynamics_node',
        name='dynamics_node',
        output='screen',
        parameters=[params_file, overrides],
    )]
    missing = _rviz_missing() if rviz else None
    if missing:
        actions.append(LogInfo(msg=f'rviz:=true, but no RViz: {missing}; the node runs '
                                   'without it'))
    elif rviz:
        config = f"{get_package_share_directory('hecker_dynamics')}/{RVIZ_CONFIG}"
        actions.append(Node(
            package='rviz2',
            executable='rviz2',
            name='rviz2',
            arguments=['-d', config, '-f', load_scene(params_file).frame_id],
            parameters=[{'use_sim_time': ParameterValue(LaunchConfiguration('use_sim_time'),
                                                        value_type=bool)}],
        ))
    return actions


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument(
            'scene', default_value='sample',
            description='shipped scene name (config/<name>.yaml) or path to a parameters file'),
        DeclareLaunchArgument(
            'use_sim_time', default_value='false', choices=['true', 'false'],
            description='follow /clock instead of the system clock'),
        DeclareLaunchArgument(
            'rviz', default_value='false', choices=['true', 'false'],
            description='also start RViz2 with the package view (TF and shape markers)'),
        DeclareLaunchArgument(
            'markers', default_value='auto', choices=['auto', 'true', 'false'],
            description="publish the shape markers (auto: on with rviz:=true, else the "
                        "scene's publish.markers)"),
        OpaqueFunction(function=_dynamics_node),
    ])
