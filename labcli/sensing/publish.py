"""Where the estimates go: JSON lines to a stream or a file, and to every client of a TCP port.

An :class:`Output` takes each line (one JSON object, no newline) as it is made; :mod:`.live`
sends every estimate and event to each output in turn.  Outputs use the standard library
only: a controller subscribes with ``nc HOST PORT`` or a socket of its own and reads one JSON
object a line.

:class:`TcpPublisher` never lets a client hold the rig up: it accepts and writes without
blocking, keeps at most ``max_backlog`` bytes for a client that reads slower than the rig
sends, and drops a client that falls further behind or goes away, saying so in one sentence
through ``notice``.
"""

from __future__ import annotations

import errno
import selectors
import socket
import sys
from collections.abc import Callable
from typing import IO, Protocol

from ..errors import ConfigError

MAX_BACKLOG = 1 << 20  # bytes a slow client may fall behind (some 3 minutes of estimates at 10 Hz)


class Output(Protocol):
    """A destination of JSON lines."""

    def publish(self, line: str) -> None:
        """Send one line (a JSON object, without its newline)."""

    def close(self) -> None:
        """Flush and let go of what the output holds."""


class JsonLines:
    """JSON lines to a text stream (stdout) or a file, flushed per line."""

    def __init__(self, stream: IO[str], *, owned: bool = False) -> None:
        self.stream = stream
        self.owned = owned

    @classmethod
    def to(cls, target: str) -> JsonLines:
        """``"-"``: standard output; anything else: a file, created or truncated."""
        if target == "-":
            return cls(sys.stdout)
        try:
            return cls(open(target, "w", encoding="utf-8", buffering=1), owned=True)  # noqa: SIM115
        except OSError as e:
            raise ConfigError(f"Cannot write the JSON lines to {target} ({e.strerror or e}).") from None

    def publish(self, line: str) -> None:
        self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.owned:
            self.stream.close()
        else:
            self.stream.flush()


def parse_tcp(url: str) -> tuple[str, int]:
    """``tcp://HOST:PORT`` -> (host, port); ConfigError in one sentence otherwise (port 0: any free port)."""
    form = "expected tcp://HOST:PORT, e.g. tcp://127.0.0.1:5555 (tcp://0.0.0.0:5555 for every interface)"
    if not url.startswith("tcp://"):
        raise ConfigError(f"Cannot publish on {url!r}: {form}.")
    host, sep, port = url[len("tcp://") :].rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ConfigError(f"Cannot publish on {url!r}: {form}.")
    return host, int(port)


class TcpPublisher:
    """The same JSON lines to every client connected to ``tcp://HOST:PORT`` (module docstring)."""

    def __init__(
        self,
        url: str,
        *,
        notice: Callable[[str], None] | None = None,
        max_backlog: int = MAX_BACKLOG,
    ) -> None:
        host, port = parse_tcp(url)
        self.notice = notice or (lambda text: None)
        self.max_backlog = max_backlog
        try:
            family = socket.AF_INET6 if ":" in host else socket.AF_INET
            self._server = socket.socket(family, socket.SOCK_STREAM)
        except OSError as e:
            raise ConfigError(f"Cannot publish on {url}: {e.strerror or e}.") from None
        try:
            self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._server.bind((host, port))
            self._server.listen(16)
            self._server.setblocking(False)
        except OSError as e:
            self._server.close()
            if e.errno == errno.EADDRINUSE:
                raise ConfigError(
                    f"Cannot publish on {url}: the port is in use; choose another port or stop the program holding it."
                ) from None
            if isinstance(e, socket.gaierror) or e.errno in (errno.EADDRNOTAVAIL, errno.EAFNOSUPPORT):
                raise ConfigError(f"Cannot publish on {url}: {host} is not an address of this machine.") from None
            raise ConfigError(f"Cannot publish on {url}: {e.strerror or e}.") from None
        self.host = host
        self.port = int(self._server.getsockname()[1])
        self._sel = selectors.DefaultSelector()
        self._sel.register(self._server, selectors.EVENT_READ)
        self._clients: dict[socket.socket, tuple[str, bytearray]] = {}
        self.served = 0  # clients accepted so far

    @property
    def url(self) -> str:
        return f"tcp://{self.host}:{self.port}"

    @property
    def clients(self) -> int:
        return len(self._clients)

    def poll(self) -> None:
        """Accept clients that are waiting, and notice those that hung up (no blocking)."""
        for key, _ in self._sel.select(timeout=0):
            sock = key.fileobj
            if sock is self._server:
                self._accept()
            elif isinstance(sock, socket.socket) and sock in self._clients:
                try:
                    data = sock.recv(4096)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    data = b""
                if not data:  # the client closed its end: what it sends otherwise is ignored
                    self._drop(sock, "disconnected")

    def _accept(self) -> None:
        while True:
            try:
                sock, addr = self._server.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            name = f"{addr[0]}:{addr[1]}"
            self._clients[sock] = (name, bytearray())
            self._sel.register(sock, selectors.EVENT_READ)
            self.served += 1
            self.notice(f"Client {name} connected to {self.url}.")

    def publish(self, line: str) -> None:
        self.poll()
        data = (line + "\n").encode("utf-8")
        for sock in list(self._clients):
            name, pending = self._clients[sock]
            pending += data
            try:
                sent = sock.send(pending)
            except (BlockingIOError, InterruptedError):
                sent = 0
            except OSError:
                self._drop(sock, "disconnected")
                continue
            del pending[:sent]
            if len(pending) > self.max_backlog:
                self._drop(sock, f"fell more than {self.max_backlog // 1024} KB behind")

    def _drop(self, sock: socket.socket, why: str) -> None:
        name, _ = self._clients.pop(sock)
        try:
            self._sel.unregister(sock)
        except (KeyError, ValueError):
            pass
        sock.close()
        self.notice(f"Client {name} {why}; publishing to the others goes on.")

    def close(self) -> None:
        for sock in list(self._clients):
            name, pending = self._clients.pop(sock)
            try:
                sock.setblocking(True)
                sock.settimeout(0.5)  # what is pending still goes out, unless the client stopped reading
                if pending:
                    sock.sendall(pending)
                sock.shutdown(socket.SHUT_WR)
            except OSError:
                pass
            sock.close()
        self._sel.close()
        self._server.close()
