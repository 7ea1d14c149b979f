"""Shared fixtures and helpers of the test suite."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"


def consistent_record(coefficients, terms="q + -q^3 + q'", omega=30.0, amps=((1, 0.01, 0.0), (3, 0.0, 2e-4)),
                      fs=2000.0, duration=3.3, t0=0.0):
    """A record that satisfies ``Q = q'' + h(q, q')`` exactly for a chosen periodic ``q``.

    ``amps`` lists ``(k, a_k, b_k)`` of ``q = sum a_k cos(k w t) + b_k sin(k w t)``; the force is
    built from the model, so the record is exact whatever the excitation looks like.
    """
    from jointid.identify.terms import library

    t = t0 + np.arange(int(round(duration * fs))) / fs
    q = np.zeros_like(t)
    v = np.zeros_like(t)
    a = np.zeros_like(t)
    for k, ak, bk in amps:
        w = k * omega
        c, s = np.cos(w * (t - t0)), np.sin(w * (t - t0))
        q += ak * c + bk * s
        v += -ak * w * s + bk * w * c
        a += -(w**2) * (ak * c + bk * s)
    Q = a + library(terms).restoring_force(q, v, coefficients)
    return t, Q, a, q, v


@pytest.fixture
def shared_data():
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data folder {SHARED_DATA} is absent")
    return SHARED_DATA


@pytest.fixture(scope="session")
def demo_run(tmp_path_factory):
    """The demo (seed 0, with figures), run once per test session for every slow test that reads it.

    Returns the :class:`~jointid.app.demo.DemoResult`; its output set is ``demo_run.out_dir``
    (report.html, results.json, figures/, campaigns/) and its console text ``demo_run.report()``.
    Tests only read it: a test that changes files copies them first.
    """
    import warnings

    from jointid.app.demo import run_demo
    from jointid.errors import JointidWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        return run_demo(tmp_path_factory.mktemp("demo_run") / "demo", progress=False, seed=0)
