"""Plain pip install of hecker_dynamics for machines without ROS (core, tools, tests).

On a ROS 2 machine the package is built by colcon from CMakeLists.txt instead.

The compiled kernel ``hecker_dynamics._kernel`` is optional here: where the C compiler or
the Python headers are missing its build fails with a warning, the install goes on, and the
package uses its pure-Python path. CMakeLists.txt builds the same sources with the same
floating-point flags (test/test_package.py checks that the two lists agree).
"""
import subprocess

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

KERNEL_SOURCES = ["src/kernel/module.c", "src/kernel/bind.c", "src/kernel/bind_forces.c",
                  "src/kernel/bind_stepper.c", "src/kernel/bind_contacts.c",
                  "src/kernel/bind_joints.c", "src/kernel/bind_raycast.c",
                  "src/kernel/forces.c", "src/kernel/steppers.c", "src/kernel/drive.c",
                  "src/kernel/manifold.c", "src/kernel/contact.c", "src/kernel/detect.c",
                  "src/kernel/warm.c", "src/kernel/islands.c", "src/kernel/solve.c",
                  "src/kernel/sleep.c", "src/kernel/solver.c", "src/kernel/joint.c",
                  "src/kernel/soft_joint.c",
                  "src/kernel/sparse.c", "src/kernel/coupled.c", "src/kernel/wide.c",
                  "src/kernel/crew.c", "src/kernel/bound.c", "src/kernel/raycast.c"]
KERNEL_HEADERS = ["src/kernel/kernel.h", "src/kernel/contact.h", "src/kernel/joint.h",
                  "src/kernel/drive.h",
                  "src/kernel/sparse.h", "src/kernel/coupled.h", "src/kernel/rows.h",
                  "src/kernel/wide.h", "src/kernel/crew.h", "src/kernel/floats.h",
                  "src/kernel/simd.h", "src/kernel/solver.h", "src/kernel/bind.h",
                  "src/kernel/raycast.h"]

#: GCC and Clang (compiler type "unix" on Linux and macOS, "mingw32" and "cygwin" on
#: Windows). No contraction of a * b + c into a fused multiply-add and no fast-math, so the
#: kernel rounds as the Python path does; these come after Python's own CFLAGS on the
#: command line, so they win over an -O3 or -ffast-math from the environment.
GNU_FLAGS = ["-std=gnu11", "-O2", "-ffp-contract=off", "-fno-fast-math"]
#: GCC alone: its scheduling before register allocation, off by default on x86, lets the
#: solver's sets of lanes overlap (src/kernel/wide.c); it only reorders operations, so the
#: bits stay the same. Clang knows neither flag.
GCC_FLAGS = ["-fschedule-insns", "-fsched-pressure"]
#: MSVC: /fp:precise does not contract from Visual Studio 2022 on.
MSVC_FLAGS = ["/fp:precise"]


def _is_gcc(command):
    """Whether the C compiler run as ``command`` is GCC (which defines __GNUC__ as Clang
    does, but not __clang__)."""
    try:
        macros = subprocess.run(list(command) + ["-dM", "-E", "-"], input="", text=True,
                                capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return False
    return "__GNUC__" in macros and "__clang__" not in macros


class KernelBuildExt(build_ext):
    """Adds the compiler-specific flags once the compiler is known."""

    def build_extensions(self):
        compiler = self.compiler.compiler_type
        for extension in self.extensions:
            if compiler in ("unix", "mingw32", "cygwin"):
                gcc = GCC_FLAGS if _is_gcc(self.compiler.compiler_so[:1]) else []
                extension.extra_compile_args = GNU_FLAGS + gcc + list(extension.extra_compile_args)
                extension.libraries = list(extension.libraries) + ["m", "pthread"]
            elif compiler == "msvc":
                extension.extra_compile_args = MSVC_FLAGS + list(extension.extra_compile_args)
        super().build_extensions()


setup(
    name="hecker_dynamics",
    version="0.1.0",
    description="2D rigid-body dynamics with angular effects (after Chris Hecker) for ROS 2",
    license="Apache-2.0",
    python_requires=">=3.10",
    packages=["hecker_dynamics", "hecker_dynamics.bags", "hecker_dynamics.batch",
              "hecker_dynamics.bench", "hecker_dynamics.contact", "hecker_dynamics.dynamics",
              "hecker_dynamics.geometry", "hecker_dynamics.integrators", "hecker_dynamics.ros",
              "hecker_dynamics.scene", "hecker_dynamics.viz", "hecker_dynamics.world",
              "hecker_dynamics.sensors", "hecker_dynamics.drives",
              "hecker_dynamics.config",
              "hecker_dynamics.interfaces"],
    # Scenes and message definitions live at the package root, as ROS packages keep them;
    # a pip install carries them inside the Python package.
    package_dir={"hecker_dynamics.config": "config", "hecker_dynamics.interfaces": "msg"},
    package_data={"hecker_dynamics": ["py.typed"],
                  "hecker_dynamics.config": ["*.yaml", "maps/*.yaml", "maps/*.pgm"],
                  "hecker_dynamics.bench": ["reference_ratios.json"],
                  "hecker_dynamics.interfaces": ["*.msg"]},
    # optional=True: a failed compile or link only warns (see the module docstring).
    ext_modules=[Extension("hecker_dynamics._kernel", sources=KERNEL_SOURCES,
                           depends=KERNEL_HEADERS, include_dirs=["src/kernel"],
                           optional=True)],
    cmdclass={"build_ext": KernelBuildExt},
    # tqdm: the command line's progress bars (replay, render, sweep, regress).
    install_requires=["numpy>=1.26", "pyyaml>=5.4", "rosbags>=0.10", "tqdm>=4.60"],
    extras_require={
        # The viz tests read rendered pictures back, so the test extra carries the viz one
        # and the MP4 encoder (imageio-ffmpeg: a 68 MB wheel, 169 MB installed, nearly all
        # of it the ffmpeg binary); the cluster tests start a real Dask cluster (about 8 s
        # and 44 MB more per venv); the Parquet table is read back with pyarrow (a 55 MB
        # wheel, 174 MB installed). Each installed here in under 3 s from pip's cache.
        # pyarrow 26 refuses numpy 1.x, which ROS 2 Jazzy ships (25 reads both).
        # pytest-xdist: scripts/test.sh runs the suite on every core, which keeps .ci/run's
        # three runs under CI's 20 minutes on two cores.
        "test": ["pytest>=7", "pytest-xdist>=3.5", "catkin_pkg>=0.5", "matplotlib>=3.6",
                 "Pillow>=9", "dask[distributed]>=2023.4", "imageio-ffmpeg>=0.4.9",
                 "pyarrow>=14,<26"],
        # Sweeps and regression suites on a Dask cluster (`--cluster ADDRESS`).
        "cluster": ["dask[distributed]>=2023.4"],
        # scripts/lint.sh: ruff and mypy as pyproject.toml configures them.
        "lint": ["ruff>=0.8", "mypy>=1.10"],
        "figures": ["matplotlib>=3.6"],
        # `hecker-dynamics render`, `plot` and `run --view` (MP4 also needs imageio-ffmpeg).
        "viz": ["matplotlib>=3.6", "Pillow>=9"],
        # Peers for `hecker-dynamics bench` (each optional; the bench skips what is missing).
        # Box2D 2.3.10 installs from a wheel; the older box2d-py needs swig to build.
        "bench": ["pymunk>=6", "Box2D>=2.3.10", "mujoco>=3.1", "matplotlib>=3.6"],
    },
    entry_points={"console_scripts": ["hecker-dynamics = hecker_dynamics.console:main"]},
)
