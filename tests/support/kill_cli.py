"""``python tests/support/kill_cli.py N labcli-args...``: run labcli, SIGKILLed at its N-th write to a
run file (:func:`support.records.kill_at_write`; N 0 prints the count at exit)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from support.records import kill_at_write  # noqa: E402

if __name__ == "__main__":
    kill_at_write(int(sys.argv[1]))
    sys.argv = ["labcli", *sys.argv[2:]]
    from labcli.cli import main

    main()
