"""The documents stay true: every command shown in README.md and docs/*.md runs.

A document is followed from the top in a fresh folder: a ```toml block whose first line is
``# file: NAME`` is written to NAME, and each ``jointid ...`` line of a shell block runs (the
package installation and the test-suite commands of the README are the ones not run here).
``examples/`` of the repository is linked into the folder, as in a checkout, unless the
document copies the packaged examples itself (``jointid example --copy``, as the README does);
a command already run with the same arguments is not run again, and the README's demo is the test
session's demo run (its output set copied).

The default run checks, fast, that every command parses with the current command line and
every file shown loads with its reader; the slow run executes the documents.
"""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

from jointid.cli import EXIT_OK, EXIT_PARTIAL, build_parser, main

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))
SHARED = REPO.parent / "shared" / "data"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def steps(path):
    """``("file", name, text)`` and ``("run", argv)`` in document order."""
    out = []
    for m in FENCE.finditer(path.read_text(encoding="utf-8")):
        lang, body = m.group(1), m.group(2)
        first = body.splitlines()[0] if body.strip() else ""
        if lang == "toml" and first.startswith("# file:"):
            out.append(("file", first.split(":", 1)[1].strip(), body))
        elif lang in ("", "bash", "sh", "console"):
            for line in body.replace("\\\n", " ").splitlines():
                for part in line.split("&&"):
                    argv = shlex.split(part, comments=True)
                    if argv[:1] == ["jointid"]:
                        out.append(("run", argv[1:]))
    return out


def _ids(paths):
    return [p.relative_to(REPO).as_posix() for p in paths]


def test_the_documents_show_commands_and_files():
    runs = {p.name: [s for s in steps(p) if s[0] == "run"] for p in DOCS}
    assert ["demo", "--out", "demo-out"] == runs["README.md"][0][1]  # the README starts with the demo
    formats = steps(REPO / "docs" / "formats.md")
    names = {s[1] for s in formats if s[0] == "file"}
    assert {"sim.toml", "lab/campaign.toml", "import.toml", "plan.toml"} <= names
    commands = {s[1][0] for s in formats if s[0] == "run"}
    assert {"simulate", "identify", "import", "study"} <= commands


@pytest.mark.parametrize("doc", DOCS, ids=_ids(DOCS))
def test_every_command_parses_and_every_file_loads(doc, tmp_path):
    parser = build_parser()
    for step in steps(doc):
        if step[0] == "run":
            argv = step[1]
            if argv[0] == "public-data":
                assert set(a for a in argv[1:] if a.startswith("--")) <= {"--out", "--only"}
                continue
            parser.parse_args(argv)  # an option renamed or removed fails here
            continue
        _, name, text = step
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        _load(path)


def _load(path):
    """Read a file shown in a document with the reader of its kind (keys and values checked)."""
    from jointid.io.campaign import read_toml

    data = read_toml(path, "document example")
    if path.name == "campaign.toml":
        from jointid.io.campaign import load_campaign

        camp = load_campaign(path.parent)  # record files need not exist to check the manifest
        assert len(camp.records) == len(data["record"])
    elif "import" in data:
        from jointid.io.importer import _validate

        (path.parent / data["import"].get("data_folder", ".")).mkdir(parents=True, exist_ok=True)
        _validate(data, path)  # the description alone; its source files are read by the slow run
    elif "joint" in data and ("matrices" in data or "modal" in data):
        from jointid.io.structure_model import read_structure_model

        if not (path.parent / "examples").exists():  # its matrix file is in examples/, as in a checkout
            (path.parent / "examples").symlink_to(REPO / "examples", target_is_directory=True)
        read_structure_model(path)
    elif "study" in data:
        from jointid.app.study import load_study_plan

        load_study_plan(path)
    else:
        from jointid.app.synthesis import load_simulation_config

        load_simulation_config(path)


def _needs_shared_data(argv):
    text = " ".join(argv)
    return argv[0] == "public-data" or "unesp" in text or "brb" in text


@pytest.mark.slow
@pytest.mark.parametrize("doc", DOCS, ids=_ids(DOCS))
def test_every_command_of_the_document_runs(doc, tmp_path, monkeypatch, capsys, request):
    todo = steps(doc)
    if not todo:
        pytest.skip(f"{doc.name} shows no command")
    copies = any(s[0] == "run" and s[1][:2] == ["example", "--copy"] for s in todo)
    if not copies:
        (tmp_path / "examples").symlink_to(REPO / "examples", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    ran, done = 0, set()
    for step in todo:
        if step[0] == "file":
            path = tmp_path / step[1]
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(step[2], encoding="utf-8")
            continue
        argv = step[1]
        if _needs_shared_data(argv) and not SHARED.is_dir() or tuple(argv) in done:
            continue
        done.add(tuple(argv))
        if len(argv) == 3 and argv[:2] == ["demo", "--out"]:
            # `jointid demo --out DIR` is the session's demo run (seed 0 and figures are the command's
            # defaults): its output set is copied, not computed a second time
            shutil.copytree(request.getfixturevalue("demo_run").out_dir, tmp_path / argv[2], symlinks=True)
            ran += 1
            continue
        code = main(argv)
        out = capsys.readouterr()
        assert code in (EXIT_OK, EXIT_PARTIAL), f"jointid {' '.join(argv)} -> {code}\n{out.err[-3000:]}"
        out_dir = argv[argv.index("--out") + 1] if "--out" in argv else None
        if out_dir is not None:
            assert (tmp_path / out_dir).is_dir(), argv
        ran += 1
    assert ran > 0
