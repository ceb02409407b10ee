"""Whether the benchmark's pyramid stands still once settled (issue 37's target 3).

    python scripts/settled_pile.py [ROWS [SECONDS [THREADS]]]   (default 100 2 2)

Runs the pyramid of ROWS rows (hecker_dynamics.bench.pyramid, sleeping off) for SECONDS
and prints its largest tilt (rad from the nearest upright), the largest speed of a box's
points (|v| plus the corner's reach times |omega|, m/s), how far the farthest box got from
its start (m), the top box's height and the stepping cost; exits 1 when a box is tilted
more than 0.1 rad or moves faster than 1 cm/s. Building the 100-row scene takes about a
minute, stepping it 2 s a few more.
"""
import dataclasses
import math
import sys
import time

import numpy as np

from hecker_dynamics import Simulation
from hecker_dynamics.bench.pyramid import BOX, pyramid, pyramid_positions

MOST_TILT = 0.1
MOST_SPEED = 0.01


def main() -> int:
    rows = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 2.0
    threads = int(sys.argv[3]) if len(sys.argv) > 3 else 2
    scene = dataclasses.replace(pyramid(rows, duration=seconds), threads=threads)
    sim = Simulation(scene)
    index = {body.name: k for k, body in enumerate(scene.bodies)}
    start = np.array(pyramid_positions(rows))[[int(b.name[3:]) for b in scene.bodies]]
    began = time.perf_counter()
    sim.advance_to(round(seconds * 1e9))
    cost = (time.perf_counter() - began) / round(seconds * 1e9 / scene.step_ns)
    q, v = sim.q, sim.v
    quarter = math.pi / 2
    tilt = np.abs(q[:, 2] - np.round(q[:, 2] / quarter) * quarter)
    speed = np.hypot(v[:, 0], v[:, 1]) + BOX / math.sqrt(2.0) * np.abs(v[:, 2])
    moved = np.hypot(*(q[:, :2] - start).T)
    top = q[index[f"box{len(scene.bodies) - 1}"], 1]
    print(f"{rows} rows after {seconds:g} s: largest tilt {tilt.max():.2e} rad, "
          f"largest point speed {speed.max():.2e} m/s ({scene.bodies[int(speed.argmax())].name}), "
          f"farthest moved {moved.max():.3f} m, top box at {top:.4f} m "
          f"(built at {start[:, 1].max():.4f} m), {1e3 * cost:.1f} ms a step")
    return 0 if tilt.max() <= MOST_TILT and speed.max() <= MOST_SPEED else 1


if __name__ == "__main__":
    sys.exit(main())
