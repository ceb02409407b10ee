"""The ring scale test: N boxes joined in a ring by damped springs, and its plain C loop.

The C loop is the same model (:func:`~.scenes.ring`) with semi-implicit Euler, written
plainly and for speed (arrays of doubles; one pass over the bodies for their arms, each
angle's cos and sin once a step, one over the springs, one over the bodies), compiled at
bench time with the system C compiler (``cc``/``gcc``/``clang``, ``-O2 -march=native``:
the fastest plain build for this machine, where it accepts the flag) into a temporary
directory and called through ctypes. Without a compiler the C line is left out.
"""
from __future__ import annotations

import ctypes
import math
import os
import shutil
import subprocess
import tempfile
import time
from typing import Optional

import numpy as np

from .measure import Outcome
from .scenes import RING_SIZE, RING_SPRING, ring_initial

__all__ = ["compiler", "compiler_version", "load_c_loop", "c_loop_flags", "c_run"]

C_SOURCE = r"""
#include <math.h>
/* Ring of n boxes (mass m, inertia I about the CM), spring s joins the front end (+half, 0)
   of box s to the back end (-half, 0) of box s+1 (the last to the first); with n == 1 the
   front end of box 0 to the fixed anchor (ax, ay). Semi-implicit Euler:
   v += h a(q, v); q += h v. State: 6n doubles (x, y, angle, vx, vy, omega per box);
   work: 5n doubles (the force and torque on each box, then its front end's arm), so that
   each box's cos and sin are taken once a step, as a user writing it for speed would. */
void ring_run(int n, long steps, double h, double m, double inertia, double half,
              double k, double rest, double c, double ax, double ay,
              double *s, double *f)
{
    double *arm = f + 3 * n;
    double h_m = h / m, h_inertia = h / inertia;
    for (long t = 0; t < steps; ++t) {
        for (int i = 0; i < n; ++i) {
            double angle = s[6 * i + 2];
            arm[2 * i] = cos(angle) * half; arm[2 * i + 1] = sin(angle) * half;
            f[3 * i] = 0.0; f[3 * i + 1] = 0.0; f[3 * i + 2] = 0.0;
        }
        for (int a = 0; a < n; ++a) {
            const double *A = s + 6 * a;
            double rax = arm[2 * a], ray = arm[2 * a + 1];
            double pax = A[0] + rax, pay = A[1] + ray;
            double vax = A[3] - A[5] * ray, vay = A[4] + A[5] * rax;
            double pbx = ax, pby = ay, vbx = 0.0, vby = 0.0, rbx = 0.0, rby = 0.0;
            int b = a + 1 == n ? 0 : a + 1;
            if (n > 1) {
                const double *B = s + 6 * b;
                rbx = -arm[2 * b]; rby = -arm[2 * b + 1];
                pbx = B[0] + rbx; pby = B[1] + rby;
                vbx = B[3] - B[5] * rby; vby = B[4] + B[5] * rbx;
            }
            double dx = pax - pbx, dy = pay - pby;
            double len = sqrt(dx * dx + dy * dy);
            double ux = dx / len, uy = dy / len;
            double mag = -(k * (len - rest) + c * ((vax - vbx) * ux + (vay - vby) * uy));
            double fx = mag * ux, fy = mag * uy;
            f[3 * a] += fx; f[3 * a + 1] += fy; f[3 * a + 2] += rax * fy - ray * fx;
            if (n > 1) {
                f[3 * b] -= fx; f[3 * b + 1] -= fy; f[3 * b + 2] -= rbx * fy - rby * fx;
            }
        }
        for (int i = 0; i < n; ++i) {
            double *S = s + 6 * i;
            S[3] += h_m * f[3 * i]; S[4] += h_m * f[3 * i + 1]; S[5] += h_inertia * f[3 * i + 2];
            S[0] += h * S[3]; S[1] += h * S[4]; S[2] += h * S[5];
        }
    }
}
"""

_LIBRARY: dict[str, object] = {}


def compiler() -> Optional[str]:
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


def compiler_version() -> str:
    cc = compiler()
    if cc is None:
        return "none"
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=20)
        return out.stdout.splitlines()[0].strip()
    except Exception:
        return cc


def load_c_loop() -> Optional[ctypes.CDLL]:
    """Compile the C loop once per process (``-O2 -march=native``, or ``-O2`` where the
    compiler refuses ``-march=native``); None without a C compiler."""
    if "lib" in _LIBRARY:
        return _LIBRARY["lib"]  # type: ignore[return-value]
    cc = compiler()
    lib = None
    if cc is not None:
        directory = tempfile.mkdtemp(prefix="hecker_bench_")
        source = os.path.join(directory, "ring.c")
        target = os.path.join(directory, "libring.so")
        with open(source, "w") as handle:
            handle.write(C_SOURCE)
        for flags in (["-O2", "-march=native"], ["-O2"]):
            result = subprocess.run([cc, *flags, "-shared", "-fPIC", source, "-o", target, "-lm"],
                                    capture_output=True, text=True, timeout=120)
            if result.returncode == 0:
                _LIBRARY["flags"] = " ".join(flags)
                break
        if result.returncode == 0:
            lib = ctypes.CDLL(target)
            d, p = ctypes.c_double, ctypes.POINTER(ctypes.c_double)
            lib.ring_run.argtypes = [ctypes.c_int, ctypes.c_long] + [d] * 9 + [p, p]
            lib.ring_run.restype = None
    _LIBRARY["lib"] = lib
    return lib


def c_loop_flags() -> str:
    """The flags the C loop was compiled with ("none" without a compiler)."""
    load_c_loop()
    return str(_LIBRARY.get("flags", "none"))


def c_run(n: int, h: float, duration: float) -> Outcome:
    """The C loop over ``duration`` from the ring's initial state; final (q, v)."""
    lib = load_c_loop()
    if lib is None:
        raise RuntimeError("no C compiler")
    state = np.array(ring_initial(n), dtype=float).reshape(-1)
    work = np.zeros(5 * n)
    steps = max(1, round(duration / h))
    half = RING_SIZE[0] / 2.0
    inertia = 1.0 * (RING_SIZE[0] ** 2 + RING_SIZE[1] ** 2) / 12.0
    x, y, a = ring_initial(1)[0][:3] if n == 1 else (0.0, 0.0, 0.0)
    ax, ay = x - half * math.cos(a), y - half * math.sin(a)
    p = ctypes.POINTER(ctypes.c_double)
    start = time.perf_counter()
    lib.ring_run(n, steps, h, 1.0, inertia, half, RING_SPRING["stiffness"],
                 RING_SPRING["rest_length"], RING_SPRING["damping"], ax, ay,
                 state.ctypes.data_as(p), work.ctypes.data_as(p))
    wall = time.perf_counter() - start
    state = state.reshape(n, 6)  # type: ignore[assignment]  # the same buffer, by body
    return Outcome(wall, state[:, :3].copy(), state[:, 3:].copy(), steps=steps)
