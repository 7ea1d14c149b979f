import json
import os

import numpy as np
import pytest

from jointid.io.results import atomic_write, write_json


def test_atomic_write_leaves_no_temporary_and_ordinary_permissions(tmp_path):
    p = atomic_write(tmp_path / "sub" / "a.txt", "hello")
    assert p.read_text() == "hello"
    assert sorted(os.listdir(tmp_path / "sub")) == ["a.txt"]
    mask = os.umask(0)
    os.umask(mask)
    assert (p.stat().st_mode & 0o777) == (0o666 & ~mask)


def test_failed_write_keeps_the_previous_file(tmp_path):
    p = write_json(tmp_path / "r.json", {"a": 1})

    class Boom:
        pass

    with pytest.raises(TypeError):
        write_json(p, {"a": Boom()})
    assert json.loads(p.read_text()) == {"a": 1}
    assert os.listdir(tmp_path) == ["r.json"]


def test_json_is_strict_and_nan_becomes_null(tmp_path):
    p = write_json(tmp_path / "r.json", {"x": np.nan, "y": np.float32(2.5), "z": np.arange(2)})
    assert json.loads(p.read_text()) == {"x": None, "y": 2.5, "z": [0, 1]}
