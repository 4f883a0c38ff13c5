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


# --------------------------------------------------------------------------- inputs bounded and regular


def test_an_input_is_read_whole_under_its_bound(tmp_path):
    from labcli.core.files import read_input

    p = tmp_path / "p.toml"
    p.write_bytes(b"x" * 1000)
    assert read_input(p, "a protocol file") == b"x" * 1000


def test_an_input_past_its_bound_is_refused_naming_both_sizes(tmp_path, monkeypatch):
    from labcli.core import files

    monkeypatch.setitem(files.INPUT_LIMITS, "a model file", 2_000_000)
    p = tmp_path / "m.json"
    with open(p, "wb") as f:
        f.truncate(3_500_000)  # sparse: the size is there without the bytes
    with pytest.raises(ConfigError) as e:
        files.read_input(p, "a model file")
    assert str(e.value) == (
        f"{p} is 3.5 MB, larger than the 2 MB a model file may be; check that it is the right file."
    )


def test_a_file_that_grows_past_its_bound_while_read_is_refused(tmp_path, monkeypatch):
    """/proc files say 0 bytes and then give more: the bound holds on what is read, not on st_size."""
    from labcli.core import files

    monkeypatch.setitem(files.INPUT_LIMITS, "a table", 100)
    with pytest.raises(ConfigError) as e:
        files.read_input("/proc/self/maps", "a table", label="maps")
    assert (
        str(e.value)
        == "maps grew past the 100 bytes a table may be while it was read; check that it is the right file."
    )


def test_a_fifo_with_no_writer_is_refused_at_once_and_a_folder_is_a_folder(tmp_path):
    from labcli.core.files import check_input, read_input

    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match="is a FIFO"):
        read_input(fifo, "a table")  # would wait for a writer forever if opened blocking
    with pytest.raises(IsADirectoryError):
        check_input(tmp_path, "a table")
    with pytest.raises(FileNotFoundError):
        check_input(tmp_path / "missing.csv", "a table")


def test_text_with_bytes_that_are_not_utf8_is_stored_with_escapes():
    from labcli.core.files import stored_text

    name = os.fsdecode(b"run\xff\xfe.h5")
    assert stored_text(name) == "run\\xff\\xfe.h5"
    assert stored_text("r\u00e9sum\u00e9.h5") == "r\u00e9sum\u00e9.h5"


@pytest.mark.parametrize(
    ("text", "is_model"),
    [
        ('{\n  "schema": "labcli-takuma-model",\n  "version": 1', True),  # read by its opening alone
        ('{"kind": "rpam-model"}', True),
        ('{"version": 1, "schema": "labcli-takuma-model"}', True),  # schema later: parsed whole
        ('{"version": 1, "note": "schema"}', False),
        ('{"schema": 3}', False),
        ("trial,set,P_L10\n1,fit,0.2\n", False),
        ('["schema", "x"]', False),
    ],
)
def test_a_model_file_is_told_from_other_files_by_its_opening_or_whole(tmp_path, text, is_model):
    from labcli.core.files import check_model_output, is_model_file

    p = tmp_path / "out.json"
    p.write_text(text)
    assert is_model_file(p) is is_model
    if not is_model:
        with pytest.raises(ConfigError, match="it is not a model file"):
            check_model_output(p)
