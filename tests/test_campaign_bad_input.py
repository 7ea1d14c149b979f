"""Bad input: each problem fails its own record with a clear message; the others finish."""

import json

import numpy as np
import pytest

from conftest import consistent_record
from jointid.cli import main
from jointid.errors import IllConditionedWarning, JointidWarning, ManifestError, RecordFileNotFoundError
from jointid.io.campaign import load_campaign, write_campaign, write_csv_record
from jointid.report.output import write_results
from jointid.app.workflow import identify_campaign

W = 30.0
COEFS = [W**2, 4e6, 0.5]


def _good(i, A):
    t, Q, a, q, v = consistent_record(COEFS, omega=W, amps=((1, A, 0.0), (3, 0.0, 5 * A**3)), fs=1000.0, duration=4.0,
                                      t0=0.37 * i)
    return t, Q, a


def _write_bad(folder, name, kind):
    t, Q, a = _good(0, 0.01)
    rel = f"records/{name}.csv"
    path = folder / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "nan":
        a = a.copy(); a[10] = np.nan
        write_csv_record(path, t, {"force": Q, "accel": a})
    elif kind == "inf":
        Q = Q.copy(); Q[3] = np.inf
        write_csv_record(path, t, {"force": Q, "accel": a})
    elif kind == "short":
        n = int(1.5 * 1000 * 2 * np.pi / W)
        write_csv_record(path, t[:n], {"force": Q[:n], "accel": a[:n]})
    elif kind == "lengths":
        lines = ["time,force,accel"] + [f"{x!r},{y!r},{z!r}" for x, y, z in zip(t, Q, a)]
        lines[-1] = lines[-1].rsplit(",", 1)[0]
        path.write_text("\n".join(lines) + "\n")
    elif kind == "nonmonotonic":
        t = t.copy(); t[20], t[21] = t[21], t[20]
        write_csv_record(path, t, {"force": Q, "accel": a})
    elif kind == "uneven":
        t = t.copy(); t[100:] += 0.5e-3
        write_csv_record(path, t, {"force": Q, "accel": a})
    elif kind == "missing_column":
        write_csv_record(path, t, {"force": Q, "acceleration": a})
    elif kind == "zero_force":
        write_csv_record(path, t, {"force": 0 * Q, "accel": a})
    elif kind == "no_frequency":
        rng = np.random.default_rng(0)
        write_csv_record(path, t, {"force": rng.standard_normal(t.size), "accel": a})
    return rel


BAD = {
    "nan": "'accel'.*non-finite",
    "inf": "'force'.*non-finite",
    "short": "periods",
    "lengths": "different lengths",
    "nonmonotonic": "increasing",
    "uneven": "uniform time step",
    "missing_column": "'accel'.*missing column",
    "zero_force": "force.*zero",
    "no_frequency": "no excitation frequency found",
}


@pytest.fixture
def bad_campaign(tmp_path):
    entries = []
    for i, A in enumerate(np.linspace(0.004, 0.012, 5)):
        t, Q, a = _good(i, A)
        rel = f"records/good{i}.csv"
        write_csv_record(tmp_path / rel, t, {"force": Q, "accel": a})
        entries.append({"file": rel, "force_level": 1.0, "preload": 120})
    for kind in BAD:
        entries.append({"file": _write_bad(tmp_path, kind, kind), "force_level": 1.0, "preload": 120})
    entries.append({"file": "records/does_not_exist.csv", "force_level": 1.0, "preload": 120})
    entries.append({"file": "../outside.csv", "force_level": 1.0, "preload": 120})
    write_campaign(tmp_path, "bad input", entries)
    return tmp_path


def test_each_bad_record_fails_alone_with_a_clear_message(bad_campaign, tmp_path):
    with pytest.warns(JointidWarning):
        res = identify_campaign(bad_campaign, n_harmonics=5)
    by_file = {r.spec.file: r for r in res.records}
    for i in range(5):
        r = by_file[f"records/good{i}.csv"]
        assert r.ok, r.error
        assert r.fit.omega1 == pytest.approx(W, rel=1e-8)
    for kind, pattern in BAD.items():
        r = by_file[f"records/{kind}.csv"]
        assert r.status == "failed", kind
        assert f"records/{kind}.csv" in r.error and "record" in r.error
        assert __import__("re").search(pattern, r.error), (kind, r.error)
    assert "not found" in by_file["records/does_not_exist.csv"].error
    assert "leaves the campaign folder" in by_file["../outside.csv"].error
    g = res.groups[0]
    assert g.pooled.k3 == pytest.approx(4e6, rel=1e-6)
    out = tmp_path / "out"
    write_results(res, out, figures=False)
    data = json.loads((out / "results.json").read_text())
    failed = [r for r in data["records"] if r["status"] == "failed"]
    assert len(failed) == len(BAD) + 2
    assert all(r["error"] for r in failed)
    assert data["groups"][0]["k3"] == pytest.approx(4e6, rel=1e-6)


def test_cli_exit_code_reports_partial_failure(bad_campaign, tmp_path, capsys):
    code = main(["identify", str(bad_campaign), "--out", str(tmp_path / "o"), "--no-figures", "--quiet", "--jobs", "2"])
    assert code == 1
    assert (tmp_path / "o" / "results.json").is_file()


def test_manifest_errors(tmp_path):
    with pytest.raises(RecordFileNotFoundError, match="campaign.toml"):
        load_campaign(tmp_path)
    (tmp_path / "campaign.toml").write_text("[campaign]\nname = 'x'\ncoordinates = 'polar'\n[[record]]\nfile='a.csv'\n")
    with pytest.raises(ManifestError, match="coordinates"):
        load_campaign(tmp_path)
    (tmp_path / "campaign.toml").write_text("[campaign\n")
    with pytest.raises(ManifestError, match="not valid TOML"):
        load_campaign(tmp_path)
    assert main(["identify", str(tmp_path), "--out", str(tmp_path / "o"), "--quiet"]) == 2


def test_unresolved_k3_is_warned_with_condition_number(tmp_path):
    rng = np.random.default_rng(4)
    t, Q, a, q, v = consistent_record(COEFS, omega=W, amps=((1, 1e-5, 0.0),), fs=1000.0, duration=4.0)
    a = a + 0.01 * a.std() * rng.standard_normal(a.size)
    write_csv_record(tmp_path / "r.csv", t, {"force": Q, "accel": a})
    write_campaign(tmp_path, "tiny", [{"file": "r.csv", "force_level": 1, "preload": 1}])
    with pytest.warns(IllConditionedWarning, match=r"k3 not resolved.*condition number"):
        res = identify_campaign(tmp_path)
    assert res.records[0].ok
    assert any("condition number" in w for w in res.records[0].summary()["warnings"])
