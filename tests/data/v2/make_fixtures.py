"""Writes float-counts.h5: a schema-2 run file as labcli wrote it before raw counts were stored as
integers (each channel's ``raw_value`` float64), two trials of tests/support/records.py.

Kept as written then (run once, with that labcli on the path); tests/core/test_store_v2.py reads it.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from support.records import FakeDevice, FakeProtocol, make_record  # noqa: E402

from labcli.core.store import RunFile  # noqa: E402

if __name__ == "__main__":
    with RunFile.create(
        str(HERE / "float-counts.h5"),
        protocol=FakeProtocol(),
        device_info=FakeDevice(),
        port="sim://?seed=1",
        force=True,
    ) as run:
        for i in (1, 2):
            run.records.write(make_record(i, n=40))
