"""Bad ``--scheduler`` addresses: one clear line, exit 2, within seconds, and no output folder.

The listeners are real loopback sockets started by the test: one that accepts and says
nothing, an HTTP server (a dashboard's port), one that writes bytes that are no dask
handshake, and a closed port.  A real scheduler must pass the same check.
"""

from __future__ import annotations

import http.server
import socket
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("distributed")

from jointid.app import parallel  # noqa: E402
from jointid.app.parallel import check_scheduler, parse_scheduler_address  # noqa: E402
from jointid.cli import main  # noqa: E402
from jointid.errors import SchedulerError  # noqa: E402
from test_study import small_plan  # noqa: E402

PLAN = """
[study]
name = "address check"
campaigns = 2
seed = 1

[[model]]
preload = "sim"
omega1 = 170.0
coefficients = { k3 = 5e6 }
amplitude_laws = { c = [0.08, 70.0, 1e4] }

[excitation]
force_levels = [1.0, 2.0]
omega_start = 160.0
omega_stop = 180.0
n_frequencies = 5

[acquisition]
fs = 2000.0
periods = 10
noise = 0.01
"""


class _Listener:
    """A loopback TCP listener in a daemon thread: ``kind`` is "silent", "garbage" or "http"."""

    def __init__(self, kind):
        self.kind, self.conns = kind, []
        if kind == "http":
            self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
            self.port = self.server.server_address[1]
            target = self.server.serve_forever
        else:
            self.sock = socket.socket()
            self.sock.bind(("127.0.0.1", 0))
            self.sock.listen(16)
            self.port = self.sock.getsockname()[1]
            target = self._serve
        threading.Thread(target=target, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            if self.kind == "garbage":
                try:  # a length header of 2**64 - 1 bytes, then text
                    conn.sendall(b"\xff" * 16 + b"not a dask scheduler\r\n" * 20)
                except OSError:
                    pass

    def close(self):
        if self.kind == "http":
            self.server.shutdown()
            self.server.server_close()
        else:
            self.sock.close()
        for c in self.conns:
            c.close()

    @property
    def address(self):
        return f"tcp://127.0.0.1:{self.port}"


@pytest.fixture(params=["silent", "garbage", "http"])
def listener(request):
    lst = _Listener(request.param)
    yield lst
    lst.close()


@pytest.fixture
def closed_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return f"tcp://127.0.0.1:{port}"


@pytest.fixture
def fast_probe(monkeypatch):
    monkeypatch.setattr(parallel, "PROBE_TIMEOUT", 1.0)


@pytest.fixture
def inputs(tmp_path):
    """A campaign folder that does not need to exist (the address is checked first) and a study plan."""
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN)
    return {"identify": str(tmp_path / "camp"), "study": str(plan)}


BAD_FORMS = ["http://127.0.0.1:8786", "foo://bar", "not a url", "tcp://", "tcp://127.0.0.1:4611686018427387904",
             "tcp://127.0.0.1:0", "tcp://127.0.0.1:http", "tcp://host/path:8786", "tcp://::1:8786", "", "  "]


def _run(capsys, command, inputs, out, address):
    t0 = time.monotonic()
    rc = main([command, inputs[command], "--out", str(out), "--scheduler", address, "--quiet"])
    elapsed = time.monotonic() - t0
    err = capsys.readouterr().err.strip().splitlines()
    return rc, err, elapsed


def _one_clear_line(rc, err, out, command):
    assert rc == 2, err
    assert len(err) == 1 and err[0].startswith(f"jointid {command}: error: "), err
    assert "Traceback" not in err[0]
    assert not out.exists()


@pytest.mark.parametrize("command", ["identify", "study"])
@pytest.mark.parametrize("address", BAD_FORMS)
def test_a_malformed_address_is_refused_at_once(capsys, inputs, tmp_path, command, address):
    out = tmp_path / "out"
    rc, err, elapsed = _run(capsys, command, inputs, out, address)
    _one_clear_line(rc, err, out, command)
    assert "scheduler address" in err[0] and elapsed < 5


@pytest.mark.parametrize("command", ["identify", "study"])
def test_a_listener_that_is_no_scheduler_is_recognised(capsys, inputs, tmp_path, listener, fast_probe, command):
    out = tmp_path / "out"
    rc, err, elapsed = _run(capsys, command, inputs, out, listener.address)
    _one_clear_line(rc, err, out, command)
    assert "is not a dask scheduler" in err[0] and elapsed < 10


@pytest.mark.parametrize("command", ["identify", "study"])
def test_a_closed_port_or_unknown_host_fails_without_waiting(capsys, inputs, tmp_path, closed_port, fast_probe,
                                                             command):
    for address in (closed_port, "tcp://no-such-host.invalid:8786"):
        out = tmp_path / "out"
        rc, err, elapsed = _run(capsys, command, inputs, out, address)
        _one_clear_line(rc, err, out, command)
        assert "cannot reach the dask scheduler" in err[0] and elapsed < 10


def test_tls_without_certificates_is_refused(capsys, inputs, tmp_path):
    import dask

    with dask.config.set({"distributed.comm.tls.ca-file": None, "distributed.comm.tls.client.cert": None}):
        rc, err, _ = _run(capsys, "study", inputs, tmp_path / "out", "tls://127.0.0.1:8786")
    _one_clear_line(rc, err, tmp_path / "out", "study")
    assert "certificates" in err[0]


def test_the_api_refuses_before_making_the_study_folder(tmp_path, listener, fast_probe):
    from jointid.app.study import run_study

    out = tmp_path / "study"
    with pytest.raises(SchedulerError, match="not a dask scheduler"):
        run_study(small_plan(campaigns=2, seed=3), out, scheduler=listener.address)
    assert not out.exists()


def test_address_forms():
    assert parse_scheduler_address("tcp://10.0.0.5:8786") == ("tcp", "10.0.0.5", 8786)
    assert parse_scheduler_address("10.0.0.5:9000") == ("tcp", "10.0.0.5", 9000)
    assert parse_scheduler_address("TCP://node-1.cluster") == ("tcp", "node-1.cluster", 8786)
    assert parse_scheduler_address("tcp://[::1]:8786") == ("tcp", "[::1]", 8786)
    assert parse_scheduler_address("inproc://10.0.0.5/123/1")[0] == "inproc"


def test_a_real_scheduler_passes_the_check():
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None) as cl:
        assert check_scheduler(cl.scheduler_address, timeout=5) == cl.scheduler_address
        assert check_scheduler(cl.scheduler_address.replace("tcp://", ""), timeout=5) == cl.scheduler_address


@pytest.mark.slow
def test_a_silent_listener_with_the_default_timeout_stops_within_25_s(tmp_path):
    """The command line as a user runs it, with the default probe time: exit 2 within 25 s."""
    lst = _Listener("silent")
    try:
        t0 = time.monotonic()
        proc = subprocess.run([sys.executable, "-m", "jointid.cli", "identify", str(tmp_path / "camp"), "--out",
                               str(tmp_path / "out"), "--scheduler", lst.address], capture_output=True, text=True,
                              timeout=60)
        elapsed = time.monotonic() - t0
    finally:
        lst.close()
    assert proc.returncode == 2 and elapsed < 25
    assert len(proc.stderr.strip().splitlines()) == 1 and "not a dask scheduler" in proc.stderr
    assert not (tmp_path / "out").exists()
