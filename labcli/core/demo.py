"""What every paper's demo shares: the output folder, unattended runs on the simulated rig.

A paper's demo (:class:`labcli.core.paper.Demo`) runs its whole paper on the
simulated rig with the same library calls the commands make; these helpers check the
folder it writes into and acquire its runs unattended, in virtual time.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ..errors import StoreError
from .acquisition import acquire
from .ui import ProgressUI

Progress = Callable[[str, int, int], None]  # (stage, done, total)


def check_outdir(outdir: Path, outputs: tuple[str, ...], force: bool, what: str = "demo") -> None:
    """Refuse a file, or a directory holding earlier output, unless ``force``."""
    if outdir.exists() and not outdir.is_dir():
        raise StoreError(f"{outdir} is a file; give a directory for the {what}'s output.")
    if not force:
        taken = [name for name in outputs if (outdir / name).exists()]
        if taken:
            raise StoreError(
                f"{outdir} already holds {what} output ({', '.join(taken[:3])}"
                f"{', ...' if len(taken) > 3 else ''}); pass --force to overwrite it "
                "or choose another directory."
            )


def simulated_port(seed: int, mode: str | None = None) -> str:
    """The ``sim://`` URL of the simulated rig ``mode`` (None: the default rig), seeded, in virtual time."""
    return f"sim://?{f'mode={mode}&' if mode else ''}seed={seed}&clock=virtual"


def acquire_unattended(path: Path, port: str, what: str, stage: str, progress: Progress | None, **options: Any) -> None:
    """One unattended run on the simulated rig, overwriting ``path``; StoreError if it stops early.

    The valves are the simulated operator's (supplied once, held for the whole run), as on the
    papers' rigs, so the demos' figures are those of the papers' protocols; ``labcli acquire`` on
    the same ``sim://`` board drives them by command (labcli.core.air).
    """
    options.setdefault("valves", "hand")
    outcome = acquire(path, port, unattended=True, force=True, ui=ProgressUI(stage, progress), **options)
    if outcome.exit_code:
        raise StoreError(f"The simulated {what} stopped early: {outcome.message}")


class Stages:
    """A demo's stages in order: each announced to ``progress`` as it starts, and timed.

    ``with stages.run(i, "fit"): ...`` runs stage ``i`` and keeps its wall time (s) under
    ``"fit"`` in :attr:`timings_s`; :meth:`done` adds the total.
    """

    def __init__(self, names: tuple[str, ...], progress: Progress | None) -> None:
        self.names = names
        self.progress = progress
        self.timings_s: dict[str, float] = {}
        self._t0 = time.perf_counter()

    @contextlib.contextmanager
    def run(self, index: int, key: str | None = None) -> Iterator[None]:
        if self.progress is not None:
            self.progress(self.names[index], 0, 0)
        t = time.perf_counter()
        yield
        if key is not None:
            self.timings_s[key] = time.perf_counter() - t

    def done(self) -> dict[str, float]:
        self.timings_s["total"] = time.perf_counter() - self._t0
        return self.timings_s
