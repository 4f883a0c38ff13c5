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
