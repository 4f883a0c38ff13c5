"""``python -m support.toy_main ARGS``: the ``labcli`` command line with the toy paper registered.

The toy paper is no installed plug-in (it registers at run time), so a test that runs
``labcli`` in its own process (``labcli sim --pty --mode toy``) starts it through here.
"""

from __future__ import annotations

from labcli.cli import main
from labcli.core import registry
from support.toy import ToyPaper

if __name__ == "__main__":
    registry.register(ToyPaper())
    main()
