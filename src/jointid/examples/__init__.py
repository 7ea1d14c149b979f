"""Example input files that come with the package: a simulation configuration, an import
description and a Monte Carlo study plan (``jointid example --list`` / ``--copy``).

The files live beside this module (package data), so that an installed jointid, from a
wheel or ``pip install .``, has them too; ``examples/`` of the repository is the same
folder. :func:`copy_examples` puts copies into a working folder, where the commands of the
README and of ``docs/`` find them as ``examples/NAME``.
"""

from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

from ..errors import JointidError, OutputError

__all__ = ["example_files", "copy_examples", "DEFAULT_FOLDER"]

#: Where :func:`copy_examples` puts the files by default (the documents' ``examples/NAME``).
DEFAULT_FOLDER = "examples"
#: Kinds of example file: name suffix -> what it is read by.
SUFFIXES = (".toml", ".npz", ".csv")
#: What a binary example file holds (a text file says it in its leading comment).
DATA_FILES = {"lap_joint.npz": "Mass and stiffness matrices (M, K, dof_names) of the free-free two-beam lap joint, "
                               "the structure model of docs/formats.md (jointid predict MODEL.toml)."}


def _first_sentence(text: str) -> str:
    """The first sentence of a file's leading comment block."""
    words = []
    for line in text.splitlines():
        line = line.strip()
        if not line.startswith("#") or line.strip("# ").startswith("jointid "):
            break
        words.append(line.lstrip("# ").strip())
    block = " ".join(w for w in words if w)
    end = block.find(". ")
    return block if end < 0 else block[:end + 1]


def example_files() -> dict:
    """``{file name: first sentence of its comment}`` of the example files shipped with jointid, by name."""
    root = resources.files(__name__)
    out = {}
    for entry in sorted(root.iterdir(), key=lambda e: e.name):
        if entry.is_file() and entry.name.endswith(SUFFIXES):
            out[entry.name] = DATA_FILES.get(entry.name) or _first_sentence(entry.read_text(encoding="utf-8"))
    return out


def copy_examples(names, to=DEFAULT_FOLDER) -> list:
    """Copy example files into the folder ``to`` (created when missing); returns the new paths.

    Parameters
    ----------
    names : str or list of str
        File names from :func:`example_files`, or ``"all"``.
    to : path, default ``"examples"``

    Raises
    ------
    JointidError
        On an unknown name (with the list of known ones).
    OutputError
        When ``to`` is a file or a file to be written exists already; nothing is copied then.
    """
    known = example_files()
    names = [names] if isinstance(names, str) else list(names)
    if names == ["all"]:
        names = list(known)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise JointidError(f"unknown example file(s) {', '.join(map(repr, unknown))}; "
                           f"known: {', '.join(known)} or 'all'")
    folder = Path(to)
    if folder.is_symlink() and not folder.exists():
        raise OutputError(f"{folder}: is a symbolic link to nothing (or a loop of links); give a real folder")
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{folder}: a folder was expected for the example files, got an existing file")
    present = [folder / n for n in dict.fromkeys(names) if (folder / n).exists() or (folder / n).is_symlink()]
    if present:
        raise OutputError(f"{', '.join(map(str, present))}: exists already and is not replaced; "
                          f"remove it or copy to another folder with --to")
    folder.mkdir(parents=True, exist_ok=True)
    root = resources.files(__name__)
    written = []
    for name in dict.fromkeys(names):
        with resources.as_file(root / name) as src:
            shutil.copyfile(src, folder / name)
        written.append(folder / name)
    return written
