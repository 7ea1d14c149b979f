"""A study's output folder: nothing lost, nothing mixed, nothing left behind.

Each case lost data or misled before: validating a resumed ``campaigns.jsonl`` of another
plan truncated it; a study killed or interrupted while writing its final files left
``study.json`` / ``statistics.csv`` of one count of campaigns beside a ``report.html`` of
another and said "earlier results are left as they were"; killed workers left their
``jointid-study-*`` scratch folders in the temporary directory.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest

from jointid.app import study as study_mod
from jointid.app.study import StudyPlan, remove_stale_scratch, run_campaign, run_study
from jointid.cli import main
from jointid.io.campaign import toml_dumps
from jointid.io.outputset import MARKER, read_marker
from test_study import small_plan

TESTS = str(Path(__file__).resolve().parent)


@pytest.fixture(scope="module")
def done2(tmp_path_factory):
    """A finished study of two campaigns with its report (copied by the tests that change it)."""
    out = tmp_path_factory.mktemp("done2") / "out"
    run_study(small_plan(campaigns=2), out, report=True)
    return out


def _copy(done2, tmp_path):
    return Path(shutil.copytree(done2, tmp_path / "out"))


def _plan_file(folder, **kw):
    path = folder / f"plan-{kw.get('campaigns', 4)}-{kw.get('seed', 3)}.toml"
    path.write_text(toml_dumps(small_plan(**kw)))
    return path


def _final_consistent(out):
    """The final files of ``out`` describe the same run and count of campaigns as its marker."""
    marker = read_marker(out)
    study = json.loads((out / "study.json").read_text())
    assert marker["kind"] == "study" and marker["run_id"] == study["run_id"]
    assert int(marker["campaigns"]) == study["n_campaigns"]
    if (out / "report.html").is_file():
        assert "report.html" in marker["files"]
        n = re.search(r"(\d+) campaigns \(", (out / "report.html").read_text()).group(1)
        assert int(n) == study["n_campaigns"]
    assert not list(out.glob(".final.*"))
    return study["n_campaigns"], study["run_id"]


@pytest.mark.parametrize("with_marker", [True, False])
def test_another_plans_torn_results_file_is_refused_and_left_as_it_was(done2, tmp_path, capsys, with_marker):
    out = _copy(done2, tmp_path)
    path = out / "campaigns.jsonl"
    data = path.read_bytes()
    path.write_bytes(data[:-len(data) // 4])  # the last line cut short, no final newline
    if not with_marker:  # a folder of an earlier version: no marker
        (out / MARKER).unlink()
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    code = main(["study", str(_plan_file(tmp_path, campaigns=2, seed=9)), "--out", str(out), "--quiet", "--no-report"])
    err = capsys.readouterr().err
    assert code == 2 and "another plan" in err and len(err.strip().splitlines()) == 1, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # not truncated, not touched


def test_the_same_plans_torn_line_is_repaired_and_resumed(done2, tmp_path):
    out = _copy(done2, tmp_path)
    ref = json.loads((done2 / "study.json").read_text())["statistics"]
    path = out / "campaigns.jsonl"
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(lines[0] + lines[1][:50])  # killed while appending campaign 1
    assert len(study_mod.read_campaign_lines(path)) == 1
    assert path.read_bytes().endswith(lines[1][:50])  # reading changes nothing
    res = run_study(small_plan(campaigns=2), out, report=False)
    assert res.n_run == 1 and json.loads(json.dumps(list(res.statistics))) == ref
    assert path.read_bytes() == (done2 / "campaigns.jsonl").read_bytes()


def test_interrupt_while_writing_the_final_files_keeps_the_last_complete_set(done2, tmp_path, capsys, monkeypatch):
    out = _copy(done2, tmp_path)
    assert _final_consistent(out)[0] == 2
    before = {n: (out / n).read_bytes() for n in ("study.json", "statistics.csv", "report.html")}
    import jointid.report.study_plots as plots

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "write_study_report", interrupted)  # Ctrl-C while the report is drawn
    code = main(["study", str(_plan_file(tmp_path, campaigns=3)), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 130 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert "all 3 campaigns are saved" in err and "last complete run (2 campaigns)" in err, err
    assert {n: (out / n).read_bytes() for n in before} == before
    assert _final_consistent(out)[0] == 2
    assert len((out / "campaigns.jsonl").read_text().splitlines()) == 3
    monkeypatch.undo()
    assert main(["study", str(_plan_file(tmp_path, campaigns=3)), "--out", str(out), "--quiet", "--no-report"]) == 0
    assert _final_consistent(out)[0] == 3


_DIE_IN_COMMIT = textwrap.dedent("""
    import os, sys
    from pathlib import Path
    sys.path.insert(0, {tests!r})
    from test_study import small_plan
    from jointid.app.study import run_study
    out, real = Path({out!r}), os.replace

    def dying(a, b):  # SIGKILL-like death right after the first final file is moved into place
        real(a, b)
        if Path(a).parent.name.endswith(".ready") and Path(b).parent == out:
            os._exit(9)

    os.replace = dying
    run_study(small_plan(campaigns=3), out, report=False)
""")


def test_a_run_killed_between_the_final_renames_is_completed_by_the_next(done2, tmp_path):
    out = _copy(done2, tmp_path)
    assert _final_consistent(out)[0] == 2
    proc = subprocess.run([sys.executable, "-c", _DIE_IN_COMMIT.format(tests=TESTS, out=str(out))], timeout=300)
    assert proc.returncode == 9
    assert list(out.glob(".final.*.ready"))  # the committed set, half moved: its marker still to come
    assert read_marker(out)["campaigns"] == "2"
    assert json.loads((out / "study.json").read_text())["n_campaigns"] == 2  # statistics.csv moved, not this one
    res = run_study(small_plan(campaigns=3), out, report=False)  # the set is completed first, then rewritten
    assert res.n_run == 0
    assert _final_consistent(out)[0] == 3


def test_report_html_of_an_earlier_count_does_not_stay_beside_new_statistics(done2, tmp_path):
    out = _copy(done2, tmp_path)
    run_study(small_plan(campaigns=3), out, report=False)
    assert not (out / "report.html").exists()
    assert _final_consistent(out)[0] == 3


@pytest.mark.parametrize("failure", ["unreachable", "interrupted"])
def test_a_failed_start_leaves_no_folder(tmp_path, monkeypatch, failure):
    import jointid.app.parallel as parallel
    from jointid.errors import SchedulerError

    def start(*a, **k):
        if failure == "interrupted":
            raise KeyboardInterrupt
        raise SchedulerError("cannot reach the dask scheduler at 'tcp://127.0.0.1:9'")

    monkeypatch.setattr(parallel, "map_tasks", start)
    with pytest.raises(SchedulerError if failure == "unreachable" else study_mod.StudyInterrupted) as info:
        run_study(small_plan(campaigns=2), tmp_path / "out", jobs=2)  # a cluster that fails to start
    assert not (tmp_path / "out").exists()
    if failure == "interrupted":
        assert str(info.value) == "no campaign was run and nothing was written"


def _scratch(folder):
    return sorted(p.name for p in Path(folder).glob("jointid-study-*"))


_CAMPAIGN = textwrap.dedent("""
    import sys, tempfile
    tempfile.tempdir = {tmp!r}
    sys.path.insert(0, {tests!r})
    from test_study import small_plan
    from jointid.app.study import StudyPlan, run_campaign
    run_campaign(StudyPlan.from_mapping(small_plan(campaigns=1)), 0)
""")


def test_scratch_folder_of_a_killed_worker_is_removed_by_the_next_campaign(tmp_path, monkeypatch):
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    proc = subprocess.Popen([sys.executable, "-c", _CAMPAIGN.format(tmp=str(scratch), tests=TESTS)])
    t0 = time.monotonic()
    while not _scratch(scratch) and time.monotonic() - t0 < 60 and proc.poll() is None:
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)  # the campaign's process dies with its scratch folder in place
    proc.wait(timeout=30)
    left = _scratch(scratch)
    assert left and left[0].startswith(f"jointid-study-{proc.pid}-")
    (scratch / "jointid-study-other").mkdir()  # not named by a process: never touched
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    seen = []
    real = study_mod.remove_stale_scratch

    def watch(*a, **k):
        seen.append(_scratch(scratch))
        return real(*a, **k)

    monkeypatch.setattr(study_mod, "remove_stale_scratch", watch)
    line = run_campaign(StudyPlan.from_mapping(small_plan(campaigns=1)), 0)
    assert line["status"] == "ok" and seen[0] == sorted(left + ["jointid-study-other"])
    assert _scratch(scratch) == ["jointid-study-other"]


def test_scratch_of_a_running_process_is_kept(tmp_path):
    (tmp_path / f"jointid-study-{os.getpid()}-abc").mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (tmp_path / f"jointid-study-{int(dead.stdout)}-def").mkdir()
    removed = remove_stale_scratch(tmp_path)
    assert [p.name for p in removed] == [f"jointid-study-{int(dead.stdout)}-def"]
    assert _scratch(tmp_path) == [f"jointid-study-{os.getpid()}-abc"]


def test_check_study_folder_accepts_an_older_study_folder(done2, tmp_path):
    out = _copy(done2, tmp_path)
    (out / MARKER).unlink()  # as written by an earlier version
    res = run_study(small_plan(campaigns=2), out, report=False)
    assert res.n_run == 0 and read_marker(out)["kind"] == "study"
    plan = StudyPlan.from_mapping(small_plan(campaigns=2))
    assert study_mod.check_study_folder(out, plan)["plan"] == plan.fingerprint


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 1.0, 3.0, 6.0, 9.0])
def test_sigkill_around_the_final_writes_never_leaves_a_mix(done2, tmp_path, delay):
    """``jointid study`` killed (SIGKILL) at moments around its final writes: the folder holds the
    last complete set, or a committed one that the next run puts in place first; never a mix."""
    out = _copy(done2, tmp_path)
    plan = _plan_file(tmp_path, campaigns=3)
    proc = subprocess.Popen([sys.executable, "-m", "jointid.cli", "study", str(plan), "--out", str(out), "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.monotonic()
    while (out / "campaigns.jsonl").read_text().count("\n") < 3 and time.monotonic() - t0 < 120:
        time.sleep(0.005)
    time.sleep(delay)  # the last campaign is saved: the final files are being written
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    ready = list(out.glob(".final.*.ready"))
    if list(out.glob(".final.*.tmp")):  # killed while writing the new set: the old set is in place
        study = json.loads((out / "study.json").read_text())
        assert study["n_campaigns"] == int(read_marker(out)["campaigns"]) == 2
        assert (out / "report.html").read_bytes() == (done2 / "report.html").read_bytes()
    elif not ready:  # before the new set was started or after its last rename: one complete set
        assert _final_consistent(out)[0] in (2, 3)
    print(f"SIGKILL {delay} s after the last campaign: exit {proc.returncode}, ready folder {bool(ready)}, "
          f"marker {read_marker(out)['campaigns']} campaigns")
    res = run_study(small_plan(campaigns=3), out, report=True)
    assert res.n_run == 0 and _final_consistent(out)[0] == 3


def test_a_plan_of_fewer_campaigns_than_the_file_gives_statistics_of_its_own(done2, tmp_path):
    """The results file holds 2 campaigns, the plan asks for 1: the final set describes 1 (and says
    so), the file keeps both lines, and no final file of the 2-campaign run stays beside it."""
    out = _copy(done2, tmp_path)
    res = run_study(small_plan(campaigns=1), out, report=False)
    assert res.n_run == 0 and len(res.campaigns) == 1
    assert _final_consistent(out)[0] == 1 and not (out / "report.html").exists()
    assert (out / "campaigns.jsonl").read_bytes() == (done2 / "campaigns.jsonl").read_bytes()
    first = json.loads((done2 / "campaigns.jsonl").read_text().splitlines()[0])
    stats = json.loads((out / "study.json").read_text())["statistics"]
    assert stats == json.loads(json.dumps(study_mod.study_statistics([first])))  # of campaign 0 alone


def test_ctrl_c_while_the_final_files_are_moved_is_held_back_and_told_truly(done2, tmp_path, monkeypatch):
    out = _copy(done2, tmp_path)
    real = os.replace

    def interrupted(a, b):
        if Path(a).parent.name.endswith(".ready"):
            os.kill(os.getpid(), signal.SIGINT)
        return real(a, b)

    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(study_mod.StudyInterrupted, match="the study was complete"):
        run_study(small_plan(campaigns=2), out, report=False)
    monkeypatch.undo()
    assert _final_consistent(out)[0] == 2 and not (out / "report.html").exists()


def test_a_torn_line_of_unknown_plan_in_an_unmarked_folder_is_refused_untouched(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "campaigns.jsonl").write_bytes(b'{"index": 0, "se')  # cut short before its plan
    with pytest.raises(study_mod.ManifestError, match="cannot be told"):
        run_study(small_plan(campaigns=1), out, report=False)
    assert (out / "campaigns.jsonl").read_bytes() == b'{"index": 0, "se' and sorted(os.listdir(out)) == ["campaigns.jsonl"]
