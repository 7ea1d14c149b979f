"""Parallel work on dask.distributed: the same results as in one process, whatever the workers do."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

distributed = pytest.importorskip("distributed")

from jointid.app.parallel import dask_client, local_cluster, map_tasks  # noqa: E402
from jointid.app.study import run_study  # noqa: E402
from jointid.app.synthesis import load_simulation_config, simulate_campaign  # noqa: E402
from jointid.app.workflow import identify_campaign  # noqa: E402
from jointid.errors import SchedulerError  # noqa: E402
from test_study import small_plan  # noqa: E402


@pytest.fixture(scope="module")
def cluster():
    """Two single-threaded worker processes on the loopback interface, no dashboard; a task that
    takes its worker down is not tried again."""
    with local_cluster(2, allowed_failures=0) as c:
        yield c


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The reference: a small study run in this process, without dask."""
    out = tmp_path_factory.mktemp("serial")
    res = run_study(small_plan(campaigns=8, seed=21), out, report=False)
    assert not res.failed
    return res, (out / "campaigns.jsonl").read_bytes(), _study_json(out)


def _study_json(out):
    """study.json without its run id (each run has its own) and its provenance (host, workers, times)."""
    d = json.loads((out / "study.json").read_text())
    assert d.pop("run_id")
    assert d.pop("provenance")["plan_fingerprint"] == d["plan_fingerprint"]
    return d


def test_two_workers_give_the_serial_results_bit_for_bit(cluster, serial, tmp_path):
    ref, lines, study = serial
    with distributed.Client(cluster) as client:
        res = run_study(small_plan(campaigns=8, seed=21), tmp_path, client=client, report=False)
        assert res.n_run == 8
        used = {ts for ts in client.run(os.getpid).values()}
    assert len(used) == 2 and os.getpid() not in used
    assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")  # loopback only
    assert (tmp_path / "campaigns.jsonl").read_bytes() == lines
    assert _study_json(tmp_path) == study
    assert res.statistics == ref.statistics


def test_a_killed_worker_does_not_change_the_study(serial, tmp_path, monkeypatch):
    """A worker process killed mid-study: its campaigns run again elsewhere; same results, all campaigns;
    the killed worker's scratch folder does not stay in the temporary directory."""
    import tempfile

    ref, lines, _ = serial
    out = tmp_path / "study"
    path = out / "campaigns.jsonl"
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))  # the workers' temporary directory
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    with local_cluster(2) as cl, distributed.Client(cl) as client:
        pids = client.run(os.getpid)
        with ThreadPoolExecutor(1) as pool:
            running = pool.submit(run_study, small_plan(campaigns=8, seed=21), out, client=client, report=False)
            t0 = time.monotonic()
            while not (path.is_file() and path.read_text().count("\n") >= 1) and time.monotonic() - t0 < 120:
                time.sleep(0.05)
            t0 = time.monotonic()  # a victim in the middle of a campaign: its scratch folder is there
            while True:
                busy = [pid for pid in pids.values() if list(scratch.glob(f"jointid-study-{pid}-*"))]
                if busy or time.monotonic() - t0 > 60:
                    break
                time.sleep(0.01)
            victim = busy[0] if busy else next(iter(pids.values()))
            n_before = path.read_text().count("\n")
            had_scratch = list(scratch.glob(f"jointid-study-{victim}-*"))
            os.kill(victim, signal.SIGKILL)
            res = running.result(timeout=300)
        assert n_before < 8  # the worker died while campaigns were still to run
        assert victim not in client.run(os.getpid).values()
    assert res.n_run == 8 and not res.failed
    assert path.read_bytes() == lines
    assert res.statistics == ref.statistics
    assert had_scratch and not list(scratch.glob("jointid-study-*"))


@pytest.mark.filterwarnings("ignore::jointid.errors.JointidWarning")
def test_identify_on_an_existing_scheduler_matches_one_process(cluster, tmp_path):
    from jointid.app.paper_example import paper_config

    cfg = paper_config(n_frequencies=7, noise=0.01, seed=2, write_frequency=False, periods=8)
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "camp")
    one = identify_campaign(camp).summary()
    many = identify_campaign(camp, scheduler=cluster.scheduler_address).summary()
    assert json.dumps(many, default=str) == json.dumps(one, default=str)


def test_map_tasks_keeps_the_order_and_reports_each_result(cluster):
    seen = []
    with distributed.Client(cluster) as client:
        out = map_tasks(divmod, [(n, 7) for n in range(20, 0, -1)], client=client,
                        on_result=lambda i, r: seen.append(i))
    assert out == [divmod(n, 7) for n in range(20, 0, -1)]
    assert sorted(seen) == list(range(20))


def test_unreachable_scheduler_is_a_clear_error():
    with pytest.raises(SchedulerError, match="tcp://127.0.0.1:9"):
        with dask_client(scheduler="tcp://127.0.0.1:9", timeout="0.5s"):
            pass


def test_serial_runs_do_not_import_dask(tmp_path):
    """jobs=1 (the default) runs in this process: dask is not imported."""
    code = f"""
import sys
from jointid.app.study import run_study
sys.path.insert(0, {str(os.path.dirname(__file__))!r})
from test_study import small_plan
res = run_study(small_plan(campaigns=1), {str(tmp_path)!r}, report=False)
assert res.n_run == 1 and not res.failed
bad = sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed'))
assert not bad, bad
"""
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_a_task_that_kills_its_workers_is_reported_not_fatal(cluster):
    with distributed.Client(cluster) as client:
        out = map_tasks(os._exit, [(3,)], client=client, on_lost=lambda i, msg: ("lost", i, msg))
        with pytest.raises(distributed.KilledWorker):
            map_tasks(os._exit, [(3,)], client=client)
        client.wait_for_workers(2, timeout=60)
    assert out[0][:2] == ("lost", 0) and "KilledWorker" in out[0][2]


def test_cleanup_runs_on_the_workers_after_the_tasks(cluster, tmp_path):
    """map_tasks(cleanup=...) runs on every worker at the end: the study removes there the scratch
    folders of workers killed during the run."""
    import functools

    from jointid.app.study import remove_stale_scratch

    dead = int(subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                              text=True).stdout)
    (tmp_path / f"jointid-study-{dead}-abc").mkdir()
    with distributed.Client(cluster) as client:
        out = map_tasks(divmod, [(7, 2), (9, 4)], client=client,
                        cleanup=functools.partial(remove_stale_scratch, str(tmp_path)))
    assert out == [(3, 1), (2, 1)]
    assert not list(tmp_path.iterdir())


def test_records_go_to_the_workers_in_chunks_and_come_back_in_order(cluster):
    """A few tasks per worker carry many calls each (their fixed cost is shared); the results are
    those of the calls one by one, in the order of the list."""
    from jointid.app.parallel import chunk_indices

    assert chunk_indices(2000, 2) == [list(range(a, a + 125)) for a in range(0, 2000, 125)]
    assert chunk_indices(5, 2) == [[0], [1], [2], [3], [4]]
    assert chunk_indices(7, 1, chunk_size=3) == [[0, 1, 2], [3, 4, 5], [6]]
    seen = []
    with distributed.Client(cluster) as client:
        out = map_tasks(divmod, [(n, 7) for n in range(300, 0, -1)], client=client, chunk_size=64,
                        on_result=lambda i, r: seen.append(i))
    assert out == [divmod(n, 7) for n in range(300, 0, -1)]
    assert sorted(seen) == list(range(300))


def test_a_chunk_that_fails_loses_only_its_failing_call(cluster):
    with distributed.Client(cluster) as client:
        out = map_tasks(_fails_on_13, [(n,) for n in range(40)], client=client, chunk_size=10,
                        on_lost=lambda i, message: ("lost", i, "ValueError" in message))
    assert out == [("lost", 13, True) if n == 13 else n * n for n in range(40)]


def _fails_on_13(n):
    if n == 13:
        raise ValueError("thirteen")
    return n * n


def test_too_few_calls_for_a_local_cluster_run_in_this_process(monkeypatch):
    from jointid.app import parallel

    monkeypatch.setattr(parallel, "local_cluster", lambda *a, **k: pytest.fail("no cluster for 5 calls"))
    assert map_tasks(divmod, [(n, 3) for n in range(5)], jobs=2, min_items=10) == [divmod(n, 3) for n in range(5)]
    assert parallel.LAST_RUN["executor"] == "in-process"


def test_local_cluster_workers_keep_the_c_library_heap_policy():
    """dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers' environment, which turns glibc's adaptive
    mmap threshold off (every large temporary faulted in afresh, ~20 ms system time per campaign): the
    local cluster's workers start without it, and without the statistical profiler."""
    import dask

    with local_cluster(1) as cl, distributed.Client(cl) as client:
        env = client.run(os.getenv, "MALLOC_TRIM_THRESHOLD_")
        profiling = client.run(dask.config.get, "distributed.worker.profile.enabled")
    assert list(env.values()) == [None]
    assert list(profiling.values()) == [False]
