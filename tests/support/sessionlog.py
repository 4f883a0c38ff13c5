"""A run file that keeps a session log in memory: the fake the engine's session recording is tested with."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from labcli.core.sessionlog import RigIdentity, SessionInfo


@dataclass
class FakeSessionLog:
    """The session-log half of a run file (:class:`labcli.core.sessionlog.SessionLog`)."""

    sessions: list[dict[str, Any]] = field(default_factory=list)
    identity: RigIdentity | None = None

    def begin_session(self, info: SessionInfo) -> None:
        self.sessions.append({"info": info, "added": [], "redone": [], "skipped": [], "ended": None})
        self.identity = info.rig

    def trial_added(self, rid: int) -> None:
        self.sessions[-1]["added"].append(rid)

    def trial_redone(self, rid: int) -> None:
        self.sessions[-1]["redone"].append(rid)

    def trial_skipped(self, rid: int) -> None:
        self.sessions[-1]["skipped"].append(rid)

    def end(self, how: str) -> None:
        self.sessions[-1]["ended"] = how

    def rig_identity(self) -> RigIdentity | None:
        return self.identity


class LoggingRunFile(FakeSessionLog):
    """A real :class:`~labcli.core.store.RunFile` with a session log beside it (delegates the rest)."""

    def __init__(self, run: Any) -> None:
        super().__init__()
        self._run = run

    def __getattr__(self, name: str) -> Any:
        return getattr(self._run, name)
