"""Many runs at once: sweeps of a scene's parameters and regression suites of bags
(``hecker-dynamics sweep`` and ``regress``, docs/batch.md). Modules:

- :mod:`.variants`: the variants of a sweep (a grid or a seeded sample of ``--set`` values);
- :mod:`.metrics`: the metrics a sweep gathers from each run and their summary;
- :mod:`.run`: the tasks the workers run and the loops that hand them to an engine;
- :mod:`.engines`: the engines (a process pool on this machine, a Dask cluster);
- :mod:`.table`: the results table (Parquet where pyarrow is installed, else CSV).

Only :mod:`hecker_dynamics.bench` and the command line import it; the modules are not
imported here, so importing one imports no other.
"""

__all__ = ["engines", "metrics", "run", "table", "variants"]
