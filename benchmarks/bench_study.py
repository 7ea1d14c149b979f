"""Benchmark: a Monte Carlo study on one and on two local dask workers.

Runs the same study (default 200 small campaigns: one preload, one or two force levels of
five frequencies, 10-period records at 1.5 kHz, noise and k3 drawn per campaign) three
times, measured in the same process:

* in this process, without dask (``jobs=1``): the baseline, and the task time;
* on a local cluster of one worker: the per-task overhead of dask against the task time;
* on a local cluster of ``--workers`` workers (default 2): the speed-up.

It prints the wall and CPU times, the ratios, the round trip of an empty task, the cluster
start-up time, the peak resident memory of each worker, the load average (a shared machine
gives a lower ratio than a quiet one: compare the CPU time with the wall time), the CPU
overhead per task (workers' and this process's CPU time less the in-process run's: two runs
one after the other, so a changing load shows in it), the paired CPU time per campaign (the
same campaigns in this process and on a worker in turn, which a changing load does not bias),
the CPU per campaign of each kind of thread (the tasks on the workers, the workers' event loops,
this process's main thread, and its scheduler, nanny and client event-loop threads), the goal
line (two workers' wall time and CPU against the in-process run), and checks that the three runs
wrote the same ``campaigns.jsonl`` byte for byte.

Then ``--rounds`` interleaved rounds (default 3 of 40 campaigns): the study in this process, on
the workers, and as as many plain Python processes side by side (no dask), each round's ratios
taken within the round.  A virtual machine's speed can drift by a quarter between two runs a
minute apart (the same 40 campaigns took 420-595 ms each in consecutive runs here), which biases
the single runs above; the rounds' medians are not biased by it, and the plain processes show
what running two computations at once costs on the machine itself, apart from dask.

    python benchmarks/bench_study.py                  # ~5 min on two quiet cores
    python benchmarks/bench_study.py --campaigns 50   # quicker
    python benchmarks/bench_study.py --dask-intervals # with dask's default periodic callbacks
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

from jointid.app.parallel import local_cluster, map_tasks
from jointid.app.study import run_study


def plan(campaigns: int) -> dict:
    return {
        "study": {"name": "benchmark", "campaigns": campaigns, "seed": 2026},
        "model": [{"preload": "sim", "omega1": 170.0, "coefficients": {"k3": 5e6},
                   "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
        "excitation": {"force_levels": [1.0], "omega_start": 162.0, "omega_stop": 178.0, "n_frequencies": 5},
        "acquisition": {"fs": 1500.0, "periods": 10, "noise": 0.01},
        "vary": {
            "acquisition.noise": {"loguniform": [0.002, 0.02]},
            "model.coefficients.k3": {"uniform": [3e6, 6e6], "random_sign": True},
            "excitation.force_levels": {"uniform": [0.6, 2.0], "size": [1, 2]},
        },
    }


def _peak_rss_mb() -> float:
    """Peak resident memory of this process (VmHWM; ``ru_maxrss`` would also hold the resident size of the
    process a worker was forked from)."""
    try:
        with open("/proc/self/status") as fh:
            return next(float(line.split()[1]) for line in fh if line.startswith("VmHWM:")) / 1024.0
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB elsewhere too (not on macOS)


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _noop(i):
    return i


def _thread_cpu():
    """CPU seconds of each thread of this process by its Python name (Linux: /proc/self/task)."""
    import threading

    tick = os.sysconf("SC_CLK_TCK")
    out = {}
    for t in threading.enumerate():
        try:
            fields = Path(f"/proc/self/task/{t.native_id}/stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, TypeError):
            continue
        out[t.name] = out.get(t.name, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return out


def _split(before, after, is_task):
    """CPU seconds between two ``_thread_cpu`` readings: (task threads, the others)."""
    d = {k: v - before.get(k, 0.0) for k, v in after.items()}
    return sum(v for k, v in d.items() if is_task(k)), sum(v for k, v in d.items() if not is_task(k))


def _is_dask_task_thread(name):
    return "Dask-Default-Threads" in name


def _warm_up():
    import jointid.app.study  # noqa: F401 - imports are a one-off cost of a worker, not of its tasks


def _task_cpu(p, index):
    """CPU time of one campaign: of the thread that ran it, and of its whole process."""
    from jointid._blas import single_threaded
    from jointid.app.study import run_campaign

    t, c = time.thread_time(), time.process_time()
    single_threaded(run_campaign)(p, index)
    return time.thread_time() - t, time.process_time() - c


def paired_cpu(p, client, n=12):
    """Median CPU per campaign in this process and on a worker, the same campaigns in turn
    (both see the same load, unlike two runs one after the other)."""
    import statistics

    from jointid.app.study import StudyPlan

    sp = StudyPlan.from_mapping(p)
    client.submit(_task_cpu, sp, 0, pure=False).result()
    _task_cpu(sp, 0)
    here, there = [], []
    for i in range(1, n + 1):
        here.append(_task_cpu(sp, i))
        there.append(client.submit(_task_cpu, sp, i, pure=False).result())
    return [(statistics.median(x[k] for x in here), statistics.median(x[k] for x in there)) for k in (0, 1)]


_SIDE = """
import json, sys, time
sys.path.insert(0, sys.argv[1])
from bench_study import plan
from jointid._blas import single_threaded
from jointid.app.study import StudyPlan, run_campaign
sp = StudyPlan.from_mapping(plan(int(sys.argv[2])))
run = single_threaded(run_campaign)
run(sp, 0)  # imports and first-call costs, as a warm worker has them
c = time.process_time()
for i in range(int(sys.argv[3]), int(sys.argv[4])):
    run(sp, i)
print(json.dumps({"cpu": time.process_time() - c}))
"""


def side_by_side(n, k):
    """CPU seconds of ``k`` plain Python processes running ``n`` campaigns between them at the same time
    (no dask): what the machine itself charges for running ``k`` computations at once."""
    import json
    import subprocess
    import sys

    here = str(Path(__file__).resolve().parent)
    bounds = [round(i * n / k) for i in range(k + 1)]
    procs = [subprocess.Popen([sys.executable, "-c", _SIDE, here, str(n), str(a), str(b)], stdout=subprocess.PIPE,
                              text=True) for a, b in zip(bounds[:-1], bounds[1:])]
    return sum(json.loads(q.communicate()[0])["cpu"] for q in procs)


def interleaved(p, n, workers, rounds, tmp):
    """Rounds of: the study in this process, on ``workers`` workers (one warm cluster), and as ``workers`` plain
    processes side by side; the ratios within each round (a machine whose speed drifts between runs biases one
    long run against the next, not the rounds' medians)."""
    import statistics

    import distributed

    rows = []
    with local_cluster(workers) as cl, distributed.Client(cl) as client:
        client.run(_warm_up)
        run_study(plan(2), tmp / "warm", client=client, report=False)
        for r in range(rounds):
            _, t_in, c_in = timed(lambda r=r: run_study(p, tmp / f"in{r}", report=False))
            cpu0 = client.run(_cpu_s)
            _, t_w, c_main = timed(lambda r=r: run_study(p, tmp / f"wk{r}", client=client, report=False))
            c_w = sum(client.run(_cpu_s).values()) - sum(cpu0.values()) + c_main
            c_side = side_by_side(n, workers)
            rows.append((t_in / t_w, c_w / c_in, c_side / c_in, c_w / c_side))
            print(f"  round {r + 1}: {workers} workers {t_in / t_w:.2f}x the in-process wall, CPU {c_w / c_in:.2f}x; "
                  f"{workers} plain processes side by side CPU {c_side / c_in:.2f}x; workers / plain {c_w / c_side:.2f}x "
                  f"(in-process {1e3 * c_in / n:.0f} ms per campaign)")
    med = [statistics.median(x) for x in zip(*rows)]
    print(f"median of {rounds} rounds: {workers} workers {med[0]:.2f}x the in-process wall time (goal >= 1.6x), CPU "
          f"{med[1]:.2f}x the in-process CPU (goal <= 1.15x); the machine's own cost of {workers} computations at once "
          f"(plain processes) {med[2]:.2f}x; dask's part {med[3]:.2f}x")
    return med


def timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaigns", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3,
                    help="interleaved rounds (in-process, workers, plain processes) after the single runs; 0: none")
    ap.add_argument("--round-campaigns", type=int, default=40, help="campaigns per interleaved round")
    ap.add_argument("--dask-intervals", action="store_true",
                    help="run the clusters with dask's own intervals of its periodic callbacks (event loop check "
                         "20 ms, system monitor 500 ms, memory monitor 100 ms) instead of the local cluster's, to "
                         "see what they cost")
    args = ap.parse_args(argv)
    if args.dask_intervals:
        from jointid.app import parallel

        parallel.WORKER_CONFIG = {k: v for k, v in parallel.WORKER_CONFIG.items()
                                  if k not in ("distributed.admin.tick.interval", "distributed.admin.system-monitor"
                                               ".interval", "distributed.worker.memory.monitor-interval")}
    import distributed

    n = args.campaigns
    p = plan(n)
    print(f"study of {n} campaigns; load average at start {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        _, t_serial, cpu_serial = timed(lambda: run_study(p, tmp / "serial", report=False))
        task = t_serial / n
        print(f"in this process (no dask):  {t_serial:7.2f} s wall, {cpu_serial:7.2f} s CPU   "
              f"task {1e3 * task:6.1f} ms")
        results, cpu_total = {}, {}
        for workers in (1, args.workers):
            t0 = time.perf_counter()
            with local_cluster(workers) as cl, distributed.Client(cl) as client:
                client.run(_warm_up)
                start = time.perf_counter() - t0
                if workers == 1:
                    (th, tw), (ph, pw) = paired_cpu(p, client)
                    print(f"paired CPU per campaign (same campaigns in turn): thread {1e3 * th:.0f} ms here, "
                          f"{1e3 * tw:.0f} ms on a worker ({tw / th:.3f}x); process {1e3 * ph:.0f} / {1e3 * pw:.0f} ms "
                          f"({pw / ph:.3f}x)")
                _, t_noop, _ = timed(lambda: map_tasks(_noop, [(i,) for i in range(n)], client=client))
                cpu0, here0, there0 = client.run(_cpu_s), _thread_cpu(), client.run(_thread_cpu)
                _, t, cpu_main = timed(lambda: run_study(p, tmp / f"w{workers}", client=client, report=False))
                cpu_workers = sum(client.run(_cpu_s).values()) - sum(cpu0.values())
                here1, there1 = _thread_cpu(), client.run(_thread_cpu)
                rss = client.run(_peak_rss_mb)
            results[workers] = t
            cpu_total[workers] = cpu_workers + cpu_main
            print(f"local cluster, {workers} worker(s): {t:7.2f} s wall (start-up and imports {start:.2f} s)   "
                  f"ratio to in-process {t_serial / t:5.2f}x")
            print(f"    CPU: workers {cpu_workers:7.2f} s, this process (client and scheduler) {cpu_main:6.2f} s; "
                  f"CPU overhead per task {1e3 * (cpu_workers + cpu_main - cpu_serial) / n:6.2f} ms")
            main, loops = _split(here0, here1, lambda name: name == "MainThread")
            tasks, worker_loops = (sum(x) for x in zip(*(_split(there0.get(w, {}), there1[w], _is_dask_task_thread)
                                                        for w in there1)))
            print(f"    CPU per campaign by thread: tasks on the workers {1e3 * tasks / n:6.1f} ms (in-process run "
                  f"{1e3 * cpu_serial / n:6.1f} ms, {tasks / cpu_serial:.3f}x), the workers' event loops "
                  f"{1e3 * worker_loops / n:5.1f} ms, this process's main thread (client, results) {1e3 * main / n:5.1f} "
                  f"ms and its other threads (scheduler, nannies, client's event loop) {1e3 * loops / n:5.1f} ms")
            print(f"    empty task round trip {1e3 * t_noop / n:6.2f} ms/task; "
                  f"peak memory per worker: {', '.join(f'{v:.0f} MB' for v in rss.values())}")
            if workers == 1:
                over = (t - t_serial) / n
                print(f"    per-task overhead {1e3 * over:6.2f} ms against a task of {1e3 * task:6.1f} ms "
                      f"({100 * over / task:.1f} %)")
        ratio = results[1] / results[args.workers]
        w = args.workers
        print(f"{w} workers: {t_serial / results[w]:.2f}x the in-process wall time (goal >= 1.6x on 2 cores), CPU "
              f"{cpu_total[w] / cpu_serial:.2f}x the in-process CPU (goal <= 1.15x)")
        print(f"speed-up {args.workers} workers / 1 worker: {ratio:.2f}x (goal >= 1.8x on 2 quiet cores); "
              f"load average now {os.getloadavg()[0]:.2f}")
        same = {(tmp / d / "campaigns.jsonl").read_bytes() for d in ("serial", "w1", f"w{args.workers}")}
        print("campaigns.jsonl identical in the three runs:", len(same) == 1)
        if args.rounds > 0:
            print(f"interleaved rounds of {args.round_campaigns} campaigns (load average {os.getloadavg()[0]:.2f}):")
            interleaved(plan(args.round_campaigns), args.round_campaigns, args.workers, args.rounds, tmp)


if __name__ == "__main__":
    main()
