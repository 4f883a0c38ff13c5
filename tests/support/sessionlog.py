"""A run file whose session log is kept in memory: the fake the engine's session recording is tested with."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from labcli.core.sessionlog import RigIdentity, SessionInfo


@dataclass
class FakeSessionLog:
    """What the engine tells a run file's ``run.sessions`` (:class:`labcli.core.sessionlog.SessionLog`)."""

    heard: list[dict[str, Any]] = field(default_factory=list)
    identity: RigIdentity | None = None

    def begin(self, info: SessionInfo) -> None:
        self.heard.append({"info": info, "added": [], "redone": [], "skipped": [], "ended": None})
        self.identity = info.rig

    def added(self, rid: int) -> None:
        self.heard[-1]["added"].append(rid)

    def redone(self, rid: int) -> None:
        self.heard[-1]["redone"].append(rid)

    def skipped(self, rid: int) -> None:
        self.heard[-1]["skipped"].append(rid)

    def end(self, how: str) -> None:
        self.heard[-1]["ended"] = how

    def rig_identity(self) -> RigIdentity | None:
        return self.identity


class LoggingRunFile:
    """A real :class:`~labcli.core.store.RunFile` whose ``sessions`` facet is a :class:`FakeSessionLog`."""

    def __init__(self, run: Any) -> None:
        self._run = run
        self.sessions = FakeSessionLog()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._run, name)
