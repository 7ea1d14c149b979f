"""What a local cluster costs beside the tasks: dask's periodic callbacks and the last chunks' wait."""

from __future__ import annotations

import heapq

import numpy as np
import pytest

from jointid.app.parallel import WORKER_CONFIG, chunk_indices, local_cluster


def _makespan(chunks, costs, workers):
    """Finish time of the last worker when the chunks are handed out in order, each to the first
    worker that is free (dask's scheduler with tasks of one priority order), ``costs[i]`` per item."""
    free = [0.0] * workers
    for c in chunks:
        heapq.heappush(free, heapq.heappop(free) + sum(costs[i] for i in c))
    return max(free)


@pytest.mark.parametrize("n, workers", [(100, 2), (2000, 2), (41, 2), (24, 2), (5, 2), (1, 2), (300, 4), (100, 1)])
def test_tapered_chunks_cover_the_list_in_order_and_shrink_to_one(n, workers):
    chunks = chunk_indices(n, workers, taper=True)
    assert [i for c in chunks for i in c] == list(range(n))
    full = len(chunk_indices(n, workers)[0])
    start = 0
    for c in chunks:
        assert 1 <= len(c) <= full  # never larger than the untapered chunks
        assert len(c) <= max(1, -(-(n - start) // (2 * workers)))  # at most 1/(2 workers) of what is left
        start += len(c)
    assert len(chunks[-1]) == 1
    assert len(chunks) <= len(chunk_indices(n, workers)) + 2 * workers * 8  # a few more tasks, not one per item


@pytest.mark.parametrize("n", [100, 120, 2000])
def test_tapered_chunks_let_two_workers_finish_together(n):
    """Items of unequal cost (a campaign of one force level or of two): with chunks of equal size one
    worker waits at the end for the other's last chunk, half a chunk on average; with the tapered
    chunks the two finish within about one item of each other."""
    workers = 2
    rng = np.random.default_rng(n)
    plain_wait, tapered_wait = [], []
    for _ in range(40):
        costs = rng.uniform(0.5, 1.5, n)
        ideal = costs.sum() / workers
        plain_wait.append(_makespan(chunk_indices(n, workers), costs, workers) - ideal)
        tapered_wait.append(_makespan(chunk_indices(n, workers, taper=True), costs, workers) - ideal)
    assert max(tapered_wait) <= 1.5  # at most one item (the longest is 1.5) beyond the ideal
    assert np.mean(tapered_wait) <= np.mean(plain_wait) / 2


def test_an_explicit_chunk_size_is_kept():
    assert chunk_indices(7, 2, chunk_size=3) == [[0, 1, 2], [3, 4, 5], [6]]


def test_the_local_cluster_runs_dask_s_periodic_callbacks_less_often():
    """The event loop health check (20 ms by default), the system monitor (500 ms) and the memory
    monitor (100 ms) wake the scheduler, each nanny and each worker and take the GIL from the task:
    the local cluster sets them to 1 s, 5 s and 500 ms, in this process and in the workers."""
    distributed = pytest.importorskip("distributed")
    import dask

    keys = ("distributed.admin.tick.interval", "distributed.admin.system-monitor.interval",
            "distributed.worker.memory.monitor-interval")
    assert [WORKER_CONFIG[k] for k in keys] == ["1s", "5s", "500ms"]
    before = [dask.config.get(k) for k in keys]
    with local_cluster(1) as cl, distributed.Client(cl) as client:
        seen = client.run(lambda: [dask.config.get(k) for k in keys])
        scheduler_tick = cl.scheduler.periodic_callbacks["tick"].callback_time
        nanny = next(iter(cl.workers.values()))
        nanny_tick = nanny.periodic_callbacks["tick"].callback_time
        nanny_memory = nanny.periodic_callbacks["memory_monitor"].callback_time
    assert list(seen.values()) == [["1s", "5s", "500ms"]]
    assert scheduler_tick == nanny_tick == 1000
    assert nanny_memory == 500
    assert [dask.config.get(k) for k in keys] == before  # this process's own configuration is left as it was
