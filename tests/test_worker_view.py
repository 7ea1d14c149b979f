"""identify on an existing cluster whose worker does not see the campaign folder.

The worker is a real ``dask worker`` process started in its own mount namespace with an
empty tmpfs mounted over the folder that holds the campaign: it runs on this machine but,
like a worker on another machine without the shared file system, finds nothing at the
campaign's path.  The run must stop before any record is identified, with one error.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

distributed = pytest.importorskip("distributed")

from jointid.app.synthesis import load_simulation_config, simulate_campaign  # noqa: E402
from jointid.app.workflow import identify_campaign  # noqa: E402
from jointid.cli import main  # noqa: E402
from jointid.errors import RecordFileNotFoundError  # noqa: E402


def _can_hide(folder) -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "--mount", "sh", "-c", f"mount -t tmpfs none '{folder}'"],
                           capture_output=True, timeout=20)
    return probe.returncode == 0


@pytest.fixture
def scheduler():
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address=None) as cl:
        yield cl


def _start_worker(address, hidden=None):
    script = f"exec {sys.executable} -m distributed.cli.dask_worker {address} --nthreads 1 --no-nanny --no-dashboard"
    if hidden is not None:
        script = f"mount -t tmpfs none '{hidden}' && {script}"
        cmd = ["unshare", "--mount", "sh", "-c", script]
    else:
        cmd = ["sh", "-c", script]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _wait_for_worker(address, proc):
    with distributed.Client(address, timeout=20) as client:
        client.wait_for_workers(1, timeout=60)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    from jointid.app.paper_example import paper_config

    root = tmp_path_factory.mktemp("shared")
    cfg = paper_config(n_frequencies=4, noise=0.01, seed=3, write_frequency=False, periods=8)
    return simulate_campaign(load_simulation_config(cfg), root / "camp")


@pytest.mark.filterwarnings("ignore::jointid.errors.JointidWarning")
def test_a_worker_that_cannot_see_the_campaign_stops_the_run_before_any_work(scheduler, campaign, tmp_path, capsys,
                                                                             monkeypatch):
    hidden = campaign.parent
    if not _can_hide(hidden):
        pytest.skip("no mount namespaces here (unshare --mount)")
    proc = _start_worker(scheduler.scheduler_address, hidden=hidden)
    try:
        _wait_for_worker(scheduler.scheduler_address, proc)
        from jointid.app import records

        calls = []
        original = records.process_record
        monkeypatch.setattr(records, "process_record", lambda *a: calls.append(a) or original(*a))
        with pytest.raises(RecordFileNotFoundError, match="does not see the input files") as info:
            identify_campaign(campaign, scheduler=scheduler.scheduler_address)
        assert "does not exist there" in str(info.value) and "nothing was run" in str(info.value)
        assert not calls
        with distributed.Client(scheduler.scheduler_address) as client:  # no task reached the scheduler
            assert client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.task_prefixes)) == 0
        out = tmp_path / "res"
        rc = main(["identify", str(campaign), "--out", str(out), "--scheduler", scheduler.scheduler_address,
                   "--quiet"])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "does not see the input files" in err[0]
        assert not out.exists()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


@pytest.mark.filterwarnings("ignore::jointid.errors.JointidWarning")
def test_a_worker_that_sees_the_campaign_runs_it(scheduler, campaign):
    proc = _start_worker(scheduler.scheduler_address)
    try:
        _wait_for_worker(scheduler.scheduler_address, proc)
        one = identify_campaign(campaign).summary()
        many = identify_campaign(campaign, scheduler=scheduler.scheduler_address).summary()
        assert json.dumps(many, default=str) == json.dumps(one, default=str)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
