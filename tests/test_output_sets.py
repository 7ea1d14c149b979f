"""Output folders: never an input, never a folder of other files, never a mix of two kinds of set.

Each case here lost data before: ``identify CAMP --out CAMP`` replaced the campaign,
``identify RES/camp --out RES`` deleted the campaign inside an earlier set, ``study --out``
onto an identify set mixed the two, ``import`` into an existing campaign left stale records.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from jointid.app.paper_example import paper_config
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.cli import main
from jointid.errors import OutputError
from jointid.io.outputset import MARKER, check_output_folder, output_set, read_marker

FAST = ["--quiet", "--no-figures", "--no-reprediction"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    cfg = paper_config(n_frequencies=5, fs=2000.0, periods=8, noise=0.01, seed=4, write_frequency=False)
    return simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("sets") / "camp")


def _tree(folder):
    """Every file below ``folder`` with its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(argv, capsys, *patterns):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, (code, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for p in patterns:
        assert p in err, err
    return err


def test_identify_out_equal_to_the_campaign_holding_results_is_refused(campaign, tmp_path, capsys):
    camp = tmp_path / "camp"
    shutil.copytree(campaign, camp)
    (camp / "results.json").write_text("{}\n")  # results of an earlier run kept beside the records
    before = _tree(camp)
    _refused(["identify", camp, "--out", camp] + FAST, capsys, "is the input")
    assert _tree(camp) == before
    # the same folder named another way
    _refused(["identify", camp, "--out", tmp_path / "x" / ".." / "camp"] + FAST, capsys, "is the input")
    assert _tree(camp) == before


def test_identify_campaign_inside_an_earlier_output_set_is_refused(campaign, tmp_path, capsys):
    res = tmp_path / "res"
    assert main(["identify", str(campaign), "--out", str(res)] + FAST) == 0
    shutil.copytree(campaign, res / "camp")
    before = _tree(res)
    _refused(["identify", res / "camp", "--out", res] + FAST, capsys, "holds the input")
    assert _tree(res) == before and (res / "camp" / "campaign.toml").is_file()


def test_output_inside_the_campaign_is_allowed_unless_it_holds_records(campaign, tmp_path, capsys):
    camp = tmp_path / "camp"
    shutil.copytree(campaign, camp)
    assert main(["identify", str(camp), "--out", str(camp / "res")] + FAST) == 0
    assert json.loads((camp / "res" / "results.json").read_text())["n_failed"] == 0
    with pytest.raises(OutputError, match="record file"):
        check_output_folder(camp / "records", "identify", [camp])


def test_an_earlier_set_with_files_of_the_user_is_not_replaced(campaign, tmp_path, capsys):
    res = tmp_path / "res"
    assert main(["identify", str(campaign), "--out", str(res)] + FAST) == 0
    (res / "notes.txt").write_text("my notes\n")
    before = _tree(res)
    _refused(["identify", campaign, "--out", res] + FAST, capsys, "notes.txt")
    assert _tree(res) == before
    (res / "notes.txt").unlink()
    first = read_marker(res)["run_id"]
    assert main(["identify", str(campaign), "--out", str(res)] + FAST) == 0  # its own set alone: replaced
    assert read_marker(res)["run_id"] != first


def test_a_folder_with_results_but_no_marker_is_not_replaced(campaign, tmp_path, capsys):
    out = tmp_path / "demo-like"
    out.mkdir()
    (out / "results.json").write_text("{}\n")
    (out / "report.html").write_text("<html></html>\n")
    before = _tree(out)
    _refused(["identify", campaign, "--out", out] + FAST, capsys, "did not write")
    assert _tree(out) == before


def test_study_onto_an_identify_set_and_back_is_refused(campaign, tmp_path, capsys):
    from test_study import small_plan
    from jointid.io.campaign import toml_dumps

    res = tmp_path / "res"
    assert main(["identify", str(campaign), "--out", str(res)] + FAST) == 0
    before = _tree(res)
    plan = tmp_path / "plan.toml"
    plan.write_text(toml_dumps(small_plan(campaigns=1)))
    _refused(["study", plan, "--out", res, "--quiet", "--no-report"], capsys, "identify output set")
    assert _tree(res) == before
    study = tmp_path / "study"
    assert main(["study", str(plan), "--out", str(study), "--quiet", "--no-report"]) == 0
    assert read_marker(study)["kind"] == "study"
    before = _tree(study)
    _refused(["identify", campaign, "--out", study] + FAST, capsys, "study output set")
    assert _tree(study) == before


def _import_sources(folder, n):
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(2000) / 1000.0
    lines = ['[campaign]\nname = "lab"\n[import]\nchannels = { force = "F", accel = "A" }\n']
    for i in range(n):
        f = 20.0 + i
        data = np.column_stack([t, np.sin(2 * np.pi * f * t), -np.sin(2 * np.pi * f * t) * (2 * np.pi * f) ** 2])
        np.savetxt(folder / f"r{i}.csv", data, delimiter=",", header="time,F,A", comments="")
        lines.append(f'[[record]]\nfile = "r{i}.csv"\nforce_level = 1\npreload = 1\nfrequency_hz = {f}\n')
    (folder / "import.toml").write_text("".join(lines))
    return folder / "import.toml"


def test_import_replaces_its_own_earlier_import_without_stale_records(tmp_path, capsys):
    out = tmp_path / "camp"
    assert main(["import", str(_import_sources(tmp_path / "lab3", 3)), "--out", str(out)]) == 0
    assert sorted(p.name for p in (out / "records").iterdir()) == ["0000.csv", "0001.csv", "0002.csv"]
    assert read_marker(out)["kind"] == "import"
    assert main(["import", str(_import_sources(tmp_path / "lab1", 1)), "--out", str(out)]) == 0
    assert sorted(p.name for p in (out / "records").iterdir()) == ["0000.csv"]  # no stale records


def test_import_into_a_campaign_of_the_user_or_the_data_folder_is_refused(campaign, tmp_path, capsys):
    desc = _import_sources(tmp_path / "lab", 2)
    camp = tmp_path / "camp"
    shutil.copytree(campaign, camp, ignore=shutil.ignore_patterns(MARKER))  # the user's own, not a simulate set
    before = _tree(camp)
    _refused(["import", desc, "--out", camp], capsys, "did not write")
    assert _tree(camp) == before
    before = _tree(tmp_path / "lab")
    _refused(["import", desc, "--out", tmp_path / "lab"], capsys, "input")
    _refused(["import", desc, "--out", tmp_path], capsys, "holds the input")
    assert _tree(tmp_path / "lab") == before


def test_output_set_of_another_kind_is_refused_and_left_alone(tmp_path):
    out = tmp_path / "o"
    with output_set(out, kind="import") as tmp:
        (tmp / "campaign.toml").write_text("x\n")
    marker = read_marker(out)
    assert marker["kind"] == "import" and marker["files"] == ["campaign.toml"]
    with pytest.raises(OutputError, match="import output set"):
        with output_set(out, kind="identify"):
            pass  # pragma: no cover
    assert (out / "campaign.toml").read_text() == "x\n" and (out / MARKER).is_file()


def test_legacy_marker_is_an_identify_set(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / MARKER).write_text("20260101T000000Z-abcdef\n")
    (out / "results.json").write_text("{}\n")
    assert read_marker(out) == {"run_id": "20260101T000000Z-abcdef", "kind": "identify", "files": None}
    check_output_folder(out, "identify")
    with pytest.raises(OutputError):
        check_output_folder(out, "study")


def test_symlink_loop_as_out_is_a_clear_error(campaign, tmp_path, capsys):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    _refused(["identify", campaign, "--out", loop] + FAST, capsys, "link")


def test_a_set_killed_between_its_two_renames_is_put_in_place_by_the_next_run(tmp_path):
    """Killed after the old set was moved aside and before the new one was moved in: the new set
    is complete (its marker is written last) and is put in place, not removed with the old one."""
    import subprocess
    import sys

    from jointid.io.outputset import remove_leftovers

    dead = int(subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                              text=True).stdout)
    out = tmp_path / "out"
    with output_set(out, "20260101T000000Z-aaaaaa", kind="identify") as tmp:
        (tmp / "results.json").write_text("old\n")
    out.rename(tmp_path / f".out.old.{dead}-20260101T000001Z-bbbbbb.tmp")
    new = tmp_path / f".out.new.{dead}-20260101T000001Z-bbbbbb.tmp"
    shutil.copytree(tmp_path / f".out.old.{dead}-20260101T000001Z-bbbbbb.tmp", new)
    (new / "results.json").write_text("new\n")
    half = tmp_path / f".out.new.{dead}-20260101T000002Z-cccccc.tmp"  # a set killed mid-write: no marker
    half.mkdir()
    remove_leftovers(out)
    assert (out / "results.json").read_text() == "new\n"
    assert not list(tmp_path.glob(".out.*"))


def test_ctrl_c_during_the_swap_is_held_back_and_says_the_new_set_is_in_place(tmp_path, monkeypatch):
    import os
    import signal

    out = tmp_path / "o"
    with output_set(out, kind="identify") as tmp:
        (tmp / "results.json").write_text("old\n")
    real = os.replace

    def interrupted(a, b):  # Ctrl-C arrives between the two renames
        if str(b) == str(out):
            os.kill(os.getpid(), signal.SIGINT)
        return real(a, b)

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt, match="complete and is in"):
        with output_set(out, kind="identify") as tmp:
            (tmp / "results.json").write_text("new\n")
    assert (out / "results.json").read_text() == "new\n" and not list(tmp_path.glob(".o.*"))


def test_other_commands_do_not_write_into_an_output_set(campaign, tmp_path, capsys):
    res = tmp_path / "res"
    assert main(["identify", str(campaign), "--out", str(res)] + FAST) == 0
    before = _tree(res)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[campaign]\nname = 'x'\n")
    _refused(["simulate", cfg, "--out", res], capsys, "identify output set")
    _refused(["demo", "--out", res, "--quiet"], capsys, "identify output set")
    assert _tree(res) == before


# ----------------------------------------------------------------------------- the demo's set, written in place
def _fake_demo(monkeypatch, *, fail=False, name="a.txt"):
    """run_demo with its work replaced by writing one file (or failing half way)."""
    import jointid.app.demo as demo

    def work(out, progress, seed, settings, figures, run_id):
        (out / "campaigns").mkdir()
        (out / "campaigns" / name).write_text(run_id)
        if fail:
            raise RuntimeError("the rig failed")
        return run_id

    monkeypatch.setattr(demo, "_run_demo", work)
    return demo.run_demo


def test_demo_set_replaces_its_own_earlier_set_and_refuses_other_files(tmp_path, monkeypatch):
    out = tmp_path / "demo-out"
    first = _fake_demo(monkeypatch, name="first.txt")(out)
    assert read_marker(out)["kind"] == "demo" and read_marker(out)["files"] == ["campaigns/first.txt"]
    second = _fake_demo(monkeypatch, name="second.txt")(out)
    assert second != first and sorted(_tree(out)) == [MARKER, "campaigns/second.txt"]  # no file of the first run
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(OutputError, match="did not write"):
        _fake_demo(monkeypatch)(tmp_path / "mine")
    assert _tree(tmp_path / "mine") == {"notes.txt": b"keep"}


def test_demo_that_fails_puts_the_earlier_set_back(tmp_path, monkeypatch):
    out = tmp_path / "demo-out"
    _fake_demo(monkeypatch, name="good.txt")(out)
    before = _tree(out)
    with pytest.raises(RuntimeError, match="rig failed"):
        _fake_demo(monkeypatch, fail=True, name="half.txt")(out)
    assert _tree(out) == before and not list(tmp_path.glob(".demo-out.*"))


def test_demo_killed_midway_is_undone_by_the_next_run(tmp_path, monkeypatch):
    """A killed writer leaves ``state=writing`` with its pid; the next run restores the earlier set."""
    from jointid.io.outputset import marker_text, remove_leftovers

    out = tmp_path / "demo-out"
    _fake_demo(monkeypatch, name="good.txt")(out)
    before = _tree(out)
    dead_pid = 2**22 + 12345  # above the kernel's pid limit: never a live process
    prev = tmp_path / f".demo-out.prev.{dead_pid}-r1.tmp"
    out.rename(prev)
    out.mkdir()
    (out / "half.txt").write_text("partial")
    (out / MARKER).write_text(marker_text("r1", "demo", (), state="writing", pid=dead_pid))
    remove_leftovers(out)
    assert _tree(out) == before and not prev.exists()


def test_interrupt_after_the_set_is_written_says_the_new_set_is_in_place(campaign, tmp_path, capsys, monkeypatch):
    """Ctrl-C while identify prints its tables: the new set is already in place, and the message says so."""
    import jointid.cli as cli

    def interrupted(args, result):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_identify_console", interrupted)
    out = tmp_path / "res"
    assert main(["identify", str(campaign), "--out", str(out)] + FAST) == 130
    err = capsys.readouterr().err
    assert "the new output set was complete and is in" in err and "left as they were" not in err
    assert read_marker(out)["kind"] == "identify" and (out / "results.json").is_file()
