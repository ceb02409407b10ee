"""The work-precision benchmark: error against cost for every integrator.

``hecker-dynamics bench`` runs it (see :mod:`hecker_dynamics.bench.run`); ``docs/benchmark.md``
explains the method. Modules:

- :mod:`.scenes`: the benchmark scenes (1)-(5), the ring of N boxes, the shipped scenes;
- :mod:`.reference`: exact solutions and an independent high-accuracy reference;
- :mod:`.measure`: timing (median of interleaved repeats) and errors;
- :mod:`.peers`: optional pymunk, Box2D and MuJoCo adapters, checked against plain loops;
- :mod:`.ring`: the ring scale test and its plain C loop;
- :mod:`.bounce`: the ball drop's closed form and its rows, with and without event
  location, against pymunk and Box2D;
- :mod:`.report`: CSV, Markdown and the work-precision figure;
- :mod:`.contacts`: the contact section (``bench --contacts``) and its targets, on
  the scenes of :mod:`.pyramid` and the shipped ones, with the peers of
  :mod:`.scene_peers`;
- :mod:`.node`: the node's own cost (``bench --node``); :mod:`.batch`: sweeps' speed-up
  (``bench --batch``).

Nothing here is imported by the core, and the peers and matplotlib are optional.
"""

__all__ = ["batch", "bounce", "box2d_v3", "contacts", "force_law", "joints",
           "measure", "node", "peers", "pyramid", "reference", "regression", "report", "ring",
           "run", "scene_peers", "scenes"]
