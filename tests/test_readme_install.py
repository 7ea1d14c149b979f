"""The README's "Using it" block, as a new user runs it: jointid installed with
``pip install .`` (not editable) into a fresh virtual environment, then every command of the
block, one by one, in an empty folder, each with the exit code the README states (0, or 1
where its comment says ``exit 1``).

The project is copied first (without .git and build products), so that the build writes
nothing into the checkout; the environment sees the installed dependencies of this Python
(``--system-site-packages``) and gets jointid itself with ``--no-deps``.  The public data
sets are found through ``JOINTID_SHARED_DATA`` (the commands that read them are left out
when ``../shared/data`` is absent).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
ANYWHERE = shutil.ignore_patterns("__pycache__", "*.egg-info", ".pytest_cache", ".hypothesis")
TOP = shutil.ignore_patterns(".git", "build", "dist", ".venv", "demo-out", "out*")  # the root's own only


def _ignore(folder, names):
    return set(ANYWHERE(folder, names)) | (set(TOP(folder, names)) if Path(folder) == REPO else set())


def using_it_block(readme: Path = REPO / "README.md") -> list:
    """``(argv, expected exit code, line)`` of each command of the README's "Using it" block."""
    text = readme.read_text(encoding="utf-8")
    section = text[text.index("## Using it"):]
    block = re.search(r"^```bash\n(.*?)^```", section, re.S | re.M).group(1)
    out = []
    for line in block.replace("\\\n", " ").splitlines():
        argv = shlex.split(line, comments=True)
        if argv[:1] != ["jointid"]:
            continue
        comment = re.search(r"\s#\s(.*)$", line)
        out.append((argv, 1 if comment and re.search(r"\bexit 1\b", comment.group(1)) else 0, line))
    return out


def test_the_block_is_read_with_its_exit_codes():
    steps = using_it_block()
    assert steps[0][0][:3] == ["jointid", "example", "--copy"]  # the examples first: the folder starts empty
    assert any(argv[1] == "modal" for argv, _, _ in steps)
    assert all(code in (0, 1) for _, code, _ in steps)


def _pip_install(python: Path, project: Path, log: Path) -> None:
    base = [str(python), "-m", "pip", "install", "--no-deps", "--no-input", "--disable-pip-version-check"]
    tries = [base + [str(project)], base + ["--no-build-isolation", str(project)]]
    outputs = []
    for cmd in tries:  # an isolated build first (as a user's), then with this Python's setuptools
        res = subprocess.run(cmd, capture_output=True, text=True)
        outputs.append(f"$ {' '.join(cmd)}\n{res.stdout[-2000:]}\n{res.stderr[-3000:]}")
        if res.returncode == 0:
            return
    log.write_text("\n".join(outputs), encoding="utf-8")
    pytest.fail("pip install . failed:\n" + "\n".join(outputs))


@pytest.mark.slow
def test_readme_using_it_runs_in_an_empty_folder_after_pip_install(tmp_path):
    project = tmp_path / "jointid-src"
    shutil.copytree(REPO, project, symlinks=True, ignore=_ignore)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    python = venv / "bin" / "python"
    _pip_install(python, project, tmp_path / "pip.log")
    work = tmp_path / "work"
    work.mkdir()
    env = {**os.environ, "MPLBACKEND": "Agg", "PATH": f"{venv / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.pop("PYTHONPATH", None)
    env.pop("JOINTID_SHARED_DATA", None)
    if SHARED.is_dir():
        env["JOINTID_SHARED_DATA"] = str(SHARED)
    where = subprocess.run([str(python), "-c", "import jointid; print(jointid.__file__)"], cwd=work, env=env,
                           capture_output=True, text=True, check=True).stdout.strip()
    assert Path(where).resolve().is_relative_to(venv.resolve()), f"not the installed copy: {where}"
    ran, wrong = [], []
    for argv, expected, line in using_it_block():
        needs_data = argv[1] == "public-data" or "unesp" in " ".join(argv)
        if needs_data and not SHARED.is_dir():
            continue
        exe = venv / "bin" / "jointid"
        res = subprocess.run([str(exe), *argv[1:]], cwd=work, env=env, capture_output=True, text=True,
                             timeout=1800)
        if res.returncode != expected:  # the later commands still run: one report of every wrong exit
            wrong.append(f"{line}\n-> exit {res.returncode}, the README says {expected}\n"
                         f"{res.stdout[-1500:]}\n{res.stderr[-2500:]}")
        elif "--out" in argv and not (work / argv[argv.index("--out") + 1]).is_dir():
            wrong.append(f"{line}\n-> no output folder")
        ran.append(argv[1])
    assert not wrong, "\n\n".join(wrong)
    assert {"example", "simulate", "identify", "backbone", "modal"} <= set(ran)
    assert (work / "results-backbone").is_dir()  # backbone's default output, beside the results folder
    # nothing came from the checkout: the examples are the package's copies
    assert not (work / "examples").is_symlink()
