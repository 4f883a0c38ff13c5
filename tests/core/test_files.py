"""Files replaced whole at any legal name length; a name past the limit refused in one sentence."""

from __future__ import annotations

import os

import pytest

from labcli.core.files import atomic_write
from labcli.errors import ConfigError


def test_a_name_at_the_file_systems_limit_is_written_and_leaves_no_temporary_file(tmp_path):
    limit = os.pathconf(tmp_path, "PC_NAME_MAX")
    path = tmp_path / ("m" * (limit - len(".json")) + ".json")
    atomic_write(path, b'{"ok": 1}\n')
    assert path.read_bytes() == b'{"ok": 1}\n'
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_a_name_past_the_limit_is_refused_in_one_sentence_and_nothing_is_made(tmp_path):
    limit = os.pathconf(tmp_path, "PC_NAME_MAX")
    path = tmp_path / ("m" * limit + ".json")
    with pytest.raises(ConfigError) as e:
        atomic_write(path, b"{}", what="the model to ")
    assert str(e.value) == (
        f"Cannot write the model to {path}: the file name is too long ({limit + 5} bytes; this file "
        f"system allows at most {limit}), so choose a shorter name."
    )
    assert list(tmp_path.iterdir()) == []
