"""What the built package holds: every subpackage, the one copy of the shipped protocols."""

from __future__ import annotations

import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on 3.10 only
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
CONFIG = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]


def test_every_subpackage_is_listed_for_the_build():
    on_disk = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "labcli").rglob("__init__.py")}
    assert set(CONFIG["packages"]) == on_disk | {"labcli.protocols"}


def test_the_shipped_protocols_are_the_top_level_folder():
    assert CONFIG["package-dir"] == {"labcli.protocols": "protocols"}
    assert (ROOT / "protocols" / "__init__.py").is_file()
    assert set(CONFIG["package-data"]["labcli.protocols"]) == {"*.toml", "*.csv"}
    shipped = {p.suffix for p in (ROOT / "protocols").iterdir() if p.is_file()}
    assert shipped <= {".toml", ".csv", ".py"}, "a shipped file of another type needs its pattern in package-data"


def test_the_version_is_written_in_one_place():
    import importlib.metadata
    import re

    import labcli
    from labcli.core import version

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert "version" not in project and "version" in project["dynamic"]
    assert CONFIG["dynamic"]["version"] == {"attr": "labcli.core.version.__version__"}
    assert labcli.__version__ is version.__version__
    assert re.fullmatch(r"\d+\.\d+\.\d+", version.__version__)
    # The installed metadata was read from that one place when the package was built.
    assert importlib.metadata.version("labcli") == version.__version__
    written = [
        p.relative_to(ROOT).as_posix()
        for p in (ROOT / "labcli").rglob("*.py")
        if re.search(rf"['\"]{re.escape(version.__version__)}['\"]", p.read_text(encoding="utf-8"))
    ]
    assert written == ["labcli/core/version.py"]
