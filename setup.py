"""Plain pip install of hecker_dynamics for machines without ROS (core, tools, tests).

On a ROS 2 machine the package is built by colcon from CMakeLists.txt instead.
"""
from setuptools import setup

setup(
    name="hecker_dynamics",
    version="0.1.0",
    description="2D rigid-body dynamics with angular effects (after Chris Hecker) for ROS 2",
    license="Apache-2.0",
    python_requires=">=3.10",
    packages=["hecker_dynamics", "hecker_dynamics.bench", "hecker_dynamics.config",
              "hecker_dynamics.interfaces"],
    # Scenes and message definitions live at the package root, as ROS packages keep them;
    # a pip install carries them inside the Python package.
    package_dir={"hecker_dynamics.config": "config", "hecker_dynamics.interfaces": "msg"},
    package_data={"hecker_dynamics.config": ["*.yaml"], "hecker_dynamics.interfaces": ["*.msg"]},
    install_requires=["numpy>=1.26", "pyyaml>=5.4", "rosbags>=0.10"],
    extras_require={
        "test": ["pytest>=7", "catkin_pkg>=0.5"],
        "figures": ["matplotlib>=3.6"],
        # Peers for `hecker-dynamics bench` (each optional; the bench skips what is missing).
        "bench": ["pymunk>=6", "box2d-py>=2.3.8", "mujoco>=3.1", "matplotlib>=3.6"],
    },
    entry_points={"console_scripts": ["hecker-dynamics = hecker_dynamics.cli:main"]},
)
