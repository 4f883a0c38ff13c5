"""The bad-input cases of ``tests/cli/test_bad_input.py``: what a case is, and the edits that make its file.

The cases themselves live in the modules of this package, one module per part of the toolkit
(``foundation`` holds the cases of the first release); :func:`all_cases` gathers them in the
order of each module's ``ORDER`` and then its name, so adding cases means adding to one module.
"""

from __future__ import annotations

import importlib
import json
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

SIM = "sim://?seed=1&clock=virtual"
PROTOCOLS = Path(__file__).resolve().parents[3] / "protocols"
TRIAL_HEADER = "trial,set,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,theta1_deg,theta2_deg,Fx_N,Fy_N"
PUSH_HEADER = "push,object,R_m,d_m,phi_deg,P_L10,P_R10,P_L20,P_R20,P_L1,P_R1,P_L2,P_R2,category"
PUSH_ROW = "pet-1,0.033,0.01,,0.2,0.2,0.2,0.2,0.21,0.19,0.2,0.2,soft"
TABLE_HEAD = "has 1 problem (rows counted as a spreadsheet shows them, the header included):"
SIM_URL_FORM = (
    "sim://[?seed=N][&rate=HZ][&noise=X][&drift=X][&clock=virtual|wall][&tau=S][&ratefactor=X]"
    "[&mode=mckibben|rpam][&faults=KIND:RATE[@X],...][&fw=1.0|1.1][&firmware=ELF][&experiment=joint|stretch]"
    "[&nominal=0|1][&reading=derived|paper][&ideal=0|1][&friction=X][&leak=X][&thermal=X][&backlash=X][&links=X][&contact=X][&pulley=X]"
    "[&potscale=X][&potlin=X][&repeat=X][&supply=MPA[,MPA,MPA,MPA]][&design=paper|thin][&realism=literature|kind]"
    "[&valves=ok|open][&valve_c=X][&valve_b=X][&flow=orifice|lag][&script=FILE]"
)


@dataclass
class Case:
    id: str
    entry: str  # which kind of input is bad
    what: str  # the case, in words, for the table
    args: list[str]  # labcli arguments
    error: list[str]  # the exact error lines (first one without "Error: ")
    code: int = 1
    files: dict[str, bytes | Callable[[Path], bytes]] = field(default_factory=dict)
    usage: str | None = None  # click usage line when click itself refuses an option
    pty: bool = False  # serve the simulated rig on a pseudo-terminal; PTY in args is its path
    firmware: dict | None = None  # or serve support.firmware.FakeFirmware(**firmware) there instead
    xfail: str | None = None  # a bug in a module still being edited (see the report)
    fifos: tuple[str, ...] = ()  # named pipes made in the folder (never opened: a reader would wait)
    timeout: float = 120  # seconds before the case counts as a hang (special files: a few)
    stdin: str | None = None  # a file to give as standard input (default: /dev/null)


def toml_edit(old: str, new: str) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        text = (world / "good.toml").read_text()
        assert old in text
        return text.replace(old, new, 1).encode()

    return make


def trial_csv(
    edit: Callable[[list[str], list[list[str]]], tuple[list[str], list[list[str]]]],
) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        lines = (world / "trials.csv").read_text().splitlines()
        header, rows = edit(lines[0].split(","), [r.split(",") for r in lines[1:6]])
        return ("\n".join(",".join(r) for r in [header, *rows]) + "\n").encode()

    return make


def set_cell(row: int, column: str, value: str):
    def edit(header, rows):
        rows[row - 2][header.index(column)] = value  # spreadsheet row numbers: header is row 1
        return header, rows

    return edit


def drop_column(column: str):
    def edit(header, rows):
        j = header.index(column)
        return header[:j] + header[j + 1 :], [r[:j] + r[j + 1 :] for r in rows]

    return edit


def model_edit(edit: Callable[[dict], object]) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        d = json.loads((world / "run.model.json").read_text())
        out = edit(d)
        return json.dumps(d if out is None else out).encode()

    return make


def cut(name: str, fraction: float) -> Callable[[Path], bytes]:
    def make(world: Path) -> bytes:
        data = (world / name).read_bytes()
        return data[: int(len(data) * fraction)]

    return make


def other_schema(world: Path) -> bytes:
    import h5py
    import numpy as np

    tmp = world / ".other.h5"
    with h5py.File(tmp, "w") as f:
        f["data"] = np.arange(10.0)
        f.attrs["creator"] = "another program"
    data = tmp.read_bytes()
    tmp.unlink()
    return data


PLAN_HEADER = "trial,set,mass_g,direction_deg\n"


def all_cases() -> list[Case]:
    """Every module's ``CASES``, by ``ORDER`` then module name; ids must be unique across modules."""
    mods = [importlib.import_module(f"{__name__}.{m.name}") for m in pkgutil.iter_modules(__path__)]
    mods.sort(key=lambda m: (getattr(m, "ORDER", 99), m.__name__))
    return [case for m in mods for case in m.CASES]
