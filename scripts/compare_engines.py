"""Start-up and per-task cost of a distributed engine on this machine (Dask or Ray).

Run by scripts/compare_engines.sh in a venv holding one engine:
    python compare_engines.py dask|ray
One round: start a local cluster of 2 single-threaded worker processes (until both run a
task), then batches of empty tasks and of tasks that sleep 10 ms and 100 ms; prints the
medians over the rounds. Overhead per task = (wall - ideal wall on 2 workers) / tasks.
"""
import sys
import time

BATCHES = ((0.0, 1000), (0.01, 400), (0.1, 60))


def work(seconds):
    if seconds:
        time.sleep(seconds)
    return seconds


def dask_round():
    from distributed import Client, LocalCluster, as_completed
    started = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None)
    client = Client(cluster)
    client.gather([client.submit(work, 0.0, pure=False, workers=[w])
                   for w in client.scheduler_info()["workers"]])
    startup = time.perf_counter() - started
    walls = []
    for seconds, count in BATCHES:
        begin = time.perf_counter()
        for future in as_completed([client.submit(work, seconds, pure=False)
                                    for _ in range(count)]):
            future.result()
        walls.append(time.perf_counter() - begin)
    client.close()
    cluster.close()
    return startup, walls


def ray_round():
    import ray
    started = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             configure_logging=False)
    remote = ray.remote(num_cpus=1)(work)
    ray.get([remote.remote(0.0) for _ in range(2)])
    startup = time.perf_counter() - started
    walls = []
    for seconds, count in BATCHES:
        begin = time.perf_counter()
        ray.get([remote.remote(seconds) for _ in range(count)])
        walls.append(time.perf_counter() - begin)
    ray.shutdown()
    return startup, walls


if __name__ == "__main__":
    engine = sys.argv[1]
    startup, walls = (dask_round if engine == "dask" else ray_round)()
    print(f"{engine} start-up of 2 workers, s\t{startup:.3f}")
    for (seconds, count), wall in zip(BATCHES, walls):
        overhead = (wall - seconds * count / 2) / count
        print(f"{engine} overhead per task of {seconds * 1e3:g} ms, ms\t{overhead * 1e3:.3f}")
