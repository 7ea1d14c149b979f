"""Kills: SIGINT and SIGKILL of a running ``jointid identify`` (a subprocess).

After SIGINT the command ends with one line on stderr and exit 130, no traceback; after
either signal the output folder holds the previous set or a complete new one, never a
mix, and the next run removes what a killed run left behind.
"""

from __future__ import annotations

import contextlib
import json
import re
import signal
import subprocess
import sys
import time

import pytest

from jointid.app.paper_example import paper_config
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.cli import main


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    cfg = paper_config(n_frequencies=12, fs=4000.0, periods=30, noise=0.02, seed=2, write_frequency=False)
    return simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("kill-camp"))


def _command(camp, out):
    return [sys.executable, "-m", "jointid.cli", "identify", str(camp), "--out", str(out), "--quiet", "--no-reprediction"]


def _consistent(out):
    """The run id of the complete set in ``out`` (results.json, report.txt and marker agree)."""
    run_id = (out / ".jointid-run").read_text().splitlines()[0]  # the marker's first line
    assert json.loads((out / "results.json").read_text())["run_id"] == run_id
    assert run_id in (out / "report.txt").read_text()
    assert run_id in (out / "report.html").read_text()
    for name in ("records.csv", "groups.csv", "damping_laws.csv"):
        assert (out / name).is_file()
    return run_id


def _kill_at(camp, out, delay, sig):
    proc = subprocess.Popen(_command(camp, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    proc.send_signal(sig)
    try:
        stdout, stderr = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # pragma: no cover - a hang is a failure
        proc.kill()
        pytest.fail(f"identify did not end within 120 s of signal {sig}")
    return proc.returncode, stderr


@pytest.mark.parametrize("delay", [2.5, pytest.param(1.5, marks=pytest.mark.slow), pytest.param(4.0, marks=pytest.mark.slow),
                                   pytest.param(6.0, marks=pytest.mark.slow)])
def test_sigint_mid_run(campaign, tmp_path, delay):
    out = tmp_path / "out"
    assert main(["identify", str(campaign), "--out", str(out), "--quiet", "--no-reprediction"]) == 0
    before = _consistent(out)
    code, stderr = _kill_at(campaign, out, delay, signal.SIGINT)
    assert "Traceback" not in stderr, stderr
    assert code in (0, 130), (code, stderr)  # 0: the run was already complete
    print(f"SIGINT after {delay} s: exit {code}")
    after = _consistent(out)
    if code == 130:
        assert len(stderr.strip().splitlines()) == 1 and "interrupted" in stderr
        # interrupted before its set was in place: the earlier set; after it (the console part): the new
        # one, and the message says so (it never claims the earlier results were kept)
        new_set = "the new output set was complete" in stderr
        assert (after == before) != new_set, stderr
        assert new_set or "earlier results are left as they were" in stderr, stderr
    else:
        assert after != before
    assert not list(tmp_path.glob(".out.*.tmp"))


@pytest.mark.parametrize("delay", [3.0, pytest.param(1.5, marks=pytest.mark.slow), pytest.param(4.5, marks=pytest.mark.slow),
                                   pytest.param(6.5, marks=pytest.mark.slow)])
def test_sigkill_mid_run(campaign, tmp_path, delay):
    out = tmp_path / "out"
    assert main(["identify", str(campaign), "--out", str(out), "--quiet", "--no-reprediction"]) == 0
    before = _consistent(out)
    code, _ = _kill_at(campaign, out, delay, signal.SIGKILL)
    after = _consistent(out)  # the old set or a complete new one
    assert code in (0, -signal.SIGKILL)
    print(f"SIGKILL after {delay} s: exit {code}")
    # killed before its set was moved into place, ``out`` holds the old set; killed after the
    # move, on its way out, the new one: either way a complete set (_consistent checked it)
    # the next run removes the killed run's temporary set and writes a new one
    assert main(["identify", str(campaign), "--out", str(out), "--quiet", "--no-reprediction"]) == 0
    assert _consistent(out) not in (before, after)
    assert not list(tmp_path.glob(".out.*.tmp"))


# ----------------------------------------------------------------------------- a lost scheduler


def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _lines(path):
    return path.read_text().count("\n") if path.is_file() else 0


@contextlib.contextmanager
def _dask_processes(n_workers=1):
    """A ``dask scheduler`` and ``dask worker`` processes on the loopback interface; yields the
    scheduler address and the scheduler's Popen (to kill it); every process is killed at the end."""
    import os

    address = f"tcp://127.0.0.1:{_free_port()}"
    procs = []
    try:
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                       "--port", address.rsplit(":", 1)[1], "--no-dashboard"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                                       "--nworkers", str(n_workers), "--no-dashboard"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        import distributed

        with distributed.Client(address, timeout="60s") as client:  # retries until the scheduler listens
            client.wait_for_workers(n_workers, timeout=120)
        yield address, procs[0]
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=30)


@pytest.mark.slow
def test_identify_losing_its_scheduler_exits_4_and_leaves_the_earlier_set(campaign, tmp_path):
    out = tmp_path / "out"
    assert main(["identify", str(campaign), "--out", str(out), "--quiet", "--no-reprediction"]) == 0
    before = _consistent(out)
    with _dask_processes() as (address, scheduler):
        proc = subprocess.Popen(_command(campaign, out)[:-2] + ["--no-reprediction", "--scheduler", address],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        seen = ""
        while proc.poll() is None:  # the progress lines: kill the scheduler once records are done
            line = proc.stderr.readline()
            seen += line
            if re.search(r"records: [1-9]\d*/", line):
                scheduler.kill()
                break
        _, rest = proc.communicate(timeout=120)
    stderr = seen + rest
    print(f"identify, scheduler killed: exit {proc.returncode}; {stderr.strip().splitlines()[-1]}")
    assert proc.returncode == 4, stderr
    assert "Traceback" not in stderr and "ERROR" not in stderr, stderr
    last = stderr.strip().splitlines()[-1]
    assert last.startswith("jointid identify: incomplete: the dask cluster was lost") and "run the same command" in last
    assert _consistent(out) == before


@pytest.mark.slow
def test_study_losing_its_scheduler_says_so_and_keeps_the_last_complete_statistics(tmp_path):
    """A real ``dask scheduler`` process killed mid-study: exit 4 with one line saying how many
    campaigns are saved and that the same command resumes; the final files of the last complete
    run stay; the rerun finishes the study without a lost or duplicated campaign."""
    from jointid.app.study import run_study
    from jointid.io.campaign import toml_dumps
    from test_study import small_plan
    from test_study_output import _final_consistent

    out = tmp_path / "out"
    run_study(small_plan(campaigns=2), out, report=False)
    before = {n: (out / n).read_bytes() for n in ("study.json", "statistics.csv")}
    plan = tmp_path / "plan.toml"
    plan.write_text(toml_dumps(small_plan(campaigns=8)))
    with _dask_processes() as (address, scheduler):
        study = subprocess.Popen([sys.executable, "-m", "jointid.cli", "study", str(plan), "--out", str(out),
                                  "--scheduler", address], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        t0 = time.monotonic()
        while _lines(out / "campaigns.jsonl") < 3 and time.monotonic() - t0 < 180 and study.poll() is None:
            time.sleep(0.05)
        assert study.poll() is None, study.communicate()
        scheduler.kill()  # SIGKILL: the scheduler dies with campaigns still to run
        try:
            _, stderr = study.communicate(timeout=120)
        except subprocess.TimeoutExpired:  # pragma: no cover - a hang is a failure
            study.kill()
            pytest.fail("the study did not end within 120 s of losing its scheduler")
    saved = _lines(out / "campaigns.jsonl")
    print(f"scheduler killed: exit {study.returncode}, {saved} campaigns saved; stderr: {stderr.strip()[-400:]}")
    assert study.returncode == 4, stderr
    assert "Traceback" not in stderr and "ERROR" not in stderr and "(100 %)" not in stderr, stderr
    last = stderr.strip().splitlines()[-1]
    assert last.startswith("jointid study: incomplete: the dask cluster was lost"), last
    assert f"{saved} of 8 campaigns are saved" in last and "run the same command again to resume" in last, last
    assert "last complete run (2 campaigns)" in last, last
    assert 3 <= saved < 8
    assert {n: (out / n).read_bytes() for n in before} == before and _final_consistent(out)[0] == 2
    res = run_study(plan, out, report=False)  # the same study again (here in this process): resumed
    assert res.n_run == 8 - saved and not res.failed
    indices = [json.loads(line)["index"] for line in (out / "campaigns.jsonl").read_text().splitlines()]
    assert indices == list(range(8))
    assert _final_consistent(out)[0] == 8


def test_sigint_during_teardown_keeps_the_exit_status(tmp_path):
    """A Ctrl-C once the command has returned (Python's teardown) neither kills it nor prints a traceback."""
    script = (
        "import atexit, os, signal, sys, time\n"
        "from jointid.cli import entry\n"
        "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(0.2)))\n"
        "sys.argv = ['jointid', 'example', '--list']\n"
        "sys.exit(entry())\n"
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr and "KeyboardInterrupt" not in proc.stderr, proc.stderr


def test_sigint_inside_a_garbage_collector_callback_is_not_lost(tmp_path):
    """A Ctrl-C raised inside a weakref callback (where Python can only print it, "Exception ignored
    in ...", and go on) reaches the command as an interruption: no traceback, exit 130.

    The callback raises the KeyboardInterrupt itself, as the signal handler does when SIGINT lands
    while the garbage collector runs it (seen once in test_sigint_mid_run)."""
    script = (
        "import sys, weakref\n"
        "import jointid.cli as cli\n"
        "class Thing: pass\n"
        "def callback(ref):\n"
        "    raise KeyboardInterrupt\n"
        "def command(args):\n"
        "    thing = Thing(); ref = weakref.ref(thing, callback)\n"
        "    del thing  # the callback runs here; its KeyboardInterrupt cannot propagate\n"
        "    for _ in range(10**7): pass\n"
        "    print('the interrupt was lost')\n"
        "    return 0\n"
        "cli.COMMANDS['example'] = command\n"
        "sys.argv = ['jointid', 'example', '--list']\n"
        "sys.exit(cli.entry())\n"
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert "Traceback" not in proc.stderr, proc.stderr
    assert "lost" not in proc.stdout
    assert proc.returncode == 130, (proc.returncode, proc.stdout, proc.stderr)
    assert proc.stderr.strip() == "jointid example: interrupted; earlier results are left as they were"
