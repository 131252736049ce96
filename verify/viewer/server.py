"""A Meshcat server that listens on the loopback interface only, and that we can stop.

meshcat 0.3.2 binds its ZeroMQ socket to 127.0.0.1 but starts its web server with
tornado's ``listen(port)``, which binds every interface; and ``Visualizer.close()``
raises. So we do not let meshcat start the server: :class:`MeshcatServer` launches
meshcat's own server code (``meshcat.servers.zmqserver.ZMQWebSocketBridge``) in a child
Python process whose tornado ``Application.listen`` is wrapped to bind the configured
loopback address. The installed package is not modified. The child's PID is known; the
server is stopped by terminating that PID (then killing it if it lingers), and an
``atexit`` hook does the same if the caller forgot.

After start-up the server's listening sockets are read from ``/proc`` (Linux) and the
start fails if any of them is bound to a non-loopback address.
"""

from __future__ import annotations

import atexit
import contextlib
import io
import ipaddress
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:  # pragma: no cover
    from ._meshcat import meshcat

from .errors import ViewerError

#: Code run by the server's child process: the host is its first argument.
_CHILD_CODE = """
import sys
import tornado.web

HOST = sys.argv[1]
_listen = tornado.web.Application.listen


def _loopback_listen(self, port, address=None, **kwargs):
    return _listen(self, port, address=HOST, **kwargs)


tornado.web.Application.listen = _loopback_listen

from meshcat.servers.zmqserver import ZMQWebSocketBridge

bridge = ZMQWebSocketBridge(host=HOST)
print("zmq_url=" + bridge.zmq_url, flush=True)
print("web_url=" + bridge.web_url, flush=True)
bridge.run()
"""

_TCP_LISTEN = "0A"


@dataclass(frozen=True)
class ServerConfig:
    """How to run the Meshcat server.

    Attributes:
        host: Address both sockets bind to; must be an IPv4 loopback address (127.x.x.x).
        start_timeout_s: Longest wait for the server to report its URLs [s].
        stop_timeout_s: Longest wait after SIGTERM before SIGKILL [s].
    """

    host: str = "127.0.0.1"
    start_timeout_s: float = 30.0
    stop_timeout_s: float = 5.0

    def __post_init__(self) -> None:
        try:
            address = ipaddress.ip_address(self.host)
            loopback = address.version == 4 and address.is_loopback  # meshcat's zmq URL is IPv4 only
        except ValueError:
            loopback = False
        if not loopback:
            raise ViewerError(f"host = {self.host!r} is invalid: expected an IPv4 loopback address such as 127.0.0.1")
        if not self.start_timeout_s > 0 or not self.stop_timeout_s > 0:
            raise ViewerError("start_timeout_s and stop_timeout_s must be > 0 s")


@dataclass(frozen=True)
class ListeningSocket:
    """A TCP socket in LISTEN state owned by a process.

    Attributes:
        address: Bound IP address ("0.0.0.0" or "::" means every interface).
        port: Bound port.
    """

    address: str
    port: int

    @property
    def is_loopback(self) -> bool:
        """True if only the local machine can connect."""
        return ipaddress.ip_address(self.address).is_loopback


def _socket_inodes(pid: int) -> set[str]:
    inodes = set()
    fd_dir = Path(f"/proc/{pid}/fd")
    for fd in fd_dir.iterdir():
        with contextlib.suppress(OSError):
            target = os.readlink(fd)
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    return inodes


def _decode_address(hex_address: str) -> str:
    raw = bytes.fromhex(hex_address)
    # /proc/net/tcp* print each 32-bit word in host (little-endian) byte order.
    words = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
    return str(ipaddress.ip_address(words))


def listening_sockets(pid: int) -> list[ListeningSocket]:
    """The TCP sockets (IPv4 and IPv6) that process ``pid`` listens on, read from /proc.

    Raises:
        ViewerError: /proc is not available (not Linux) or the process does not exist.
    """
    try:
        inodes = _socket_inodes(pid)
    except OSError as exc:
        raise ViewerError(f"cannot read the sockets of process {pid}: {exc}") from None
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) < 10 or fields[3] != _TCP_LISTEN or fields[9] not in inodes:
                continue
            address, port = fields[1].split(":")
            found.append(ListeningSocket(_decode_address(address), int(port, 16)))
    return found


def _port_of(url: str) -> int:
    return int(url.rsplit(":", 1)[1].split("/", 1)[0])


class MeshcatServer:
    """A loopback-only Meshcat server in a child process; a context manager.

    Usage::

        with MeshcatServer() as server:
            vis = server.visualizer()
            ...
        # the server process is gone here

    Attributes:
        config: The settings.
        pid: PID of the server process (None before start).
        zmq_url: ZeroMQ URL the Python client connects to.
        web_url: URL to open in a browser.
    """

    def __init__(self, config: ServerConfig | None = None) -> None:
        self.config = config if config is not None else ServerConfig()
        self.pid: int | None = None
        self.zmq_url: str | None = None
        self.web_url: str | None = None
        self._proc: subprocess.Popen | None = None
        self._log: io.BufferedRandom | None = None
        self._clients: list[meshcat.Visualizer] = []

    @property
    def zmq_port(self) -> int:
        """Port of the ZeroMQ socket."""
        if self.zmq_url is None:
            raise ViewerError("the Meshcat server is not running")
        return _port_of(self.zmq_url)

    @property
    def web_port(self) -> int:
        """Port of the web server."""
        if self.web_url is None:
            raise ViewerError("the Meshcat server is not running")
        return _port_of(self.web_url)

    @property
    def running(self) -> bool:
        """True while the server process is alive."""
        return self._proc is not None and self._proc.poll() is None

    def start(self) -> MeshcatServer:
        """Start the server process and wait until it reports both URLs.

        Raises:
            ViewerError: already started, the process died, it did not report its URLs in
                time, or one of its sockets listens on a non-loopback address.
        """
        if self._proc is not None:
            raise ViewerError("the Meshcat server was already started")
        self._log = tempfile.TemporaryFile()
        self._proc = subprocess.Popen(
            [sys.executable, "-u", "-c", _CHILD_CODE, self.config.host],
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        self.pid = self._proc.pid
        atexit.register(self.stop)
        try:
            self._wait_for_urls()
            self._check_loopback()
        except BaseException:
            self.stop()
            raise
        return self

    def _read_log(self) -> str:
        """Everything the server process has written so far, read without moving the file offset:
        the process writes through the same open file (shared offset), so a seek here could make
        its next line overwrite the start of the log (a URL line lost, the start timing out)."""
        assert self._log is not None
        descriptor = self._log.fileno()
        return os.pread(descriptor, os.fstat(descriptor).st_size, 0).decode("utf-8", "replace")

    def _wait_for_urls(self) -> None:
        assert self._proc is not None
        deadline = time.monotonic() + self.config.start_timeout_s
        while time.monotonic() < deadline:
            text = self._read_log()
            urls = dict(line.split("=", 1) for line in text.splitlines() if line.startswith(("zmq_url=", "web_url=")))
            if "zmq_url" in urls and "web_url" in urls:
                self.zmq_url, self.web_url = urls["zmq_url"].strip(), urls["web_url"].strip()
                return
            if self._proc.poll() is not None:
                last = text.strip().splitlines()[-1:] or ["no output"]
                raise ViewerError(f"the Meshcat server exited with code {self._proc.returncode}: {last[0]}")
            time.sleep(0.02)
        raise ViewerError(f"the Meshcat server did not start within {self.config.start_timeout_s:g} s")

    def _check_loopback(self) -> None:
        assert self.pid is not None
        if not sys.platform.startswith("linux"):
            return  # /proc is Linux only; the bind address is forced all the same.
        try:
            sockets = listening_sockets(self.pid)
        except ViewerError:
            return  # /proc unreadable here: nothing to check (tests check it on Linux CI)
        exposed = [s for s in sockets if not s.is_loopback]
        if exposed:
            raise ViewerError(f"the Meshcat server listens beyond loopback: {exposed}")

    def visualizer(self) -> meshcat.Visualizer:
        """A new ``meshcat.Visualizer`` client connected to this server."""
        from ._meshcat import meshcat

        if not self.running:
            raise ViewerError("the Meshcat server is not running")
        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL; we do it ourselves
            vis = meshcat.Visualizer(zmq_url=self.zmq_url)
        self._clients.append(vis)
        return vis

    def stop(self) -> None:
        """Terminate the server process by its PID (SIGTERM, then SIGKILL); idempotent."""
        atexit.unregister(self.stop)
        for vis in self._clients:
            with contextlib.suppress(Exception):
                vis.window.zmq_socket.close(linger=0)
        self._clients.clear()
        proc, self._proc = self._proc, None
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=self.config.stop_timeout_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(proc.pid, signal.SIGKILL)
                proc.wait()
        if self._log is not None:
            self._log.close()
            self._log = None

    def __enter__(self) -> MeshcatServer:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()


def serve_until_interrupted(server: MeshcatServer, hold_s: float | None = None, out: TextIO | None = None) -> None:
    """Print the server's URL and block for ``hold_s`` seconds, or until Ctrl-C or SIGTERM
    if None (SIGTERM is turned into a clean return so the caller's ``with`` stops the server).

    Raises:
        ViewerError: the server process died while serving.
    """
    out = out if out is not None else sys.stdout

    def _terminate(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    # The handler goes in before the URL is announced: whoever reads the URL may send SIGTERM at once.
    previous = (
        signal.signal(signal.SIGTERM, _terminate) if threading.current_thread() is threading.main_thread() else None
    )
    try:
        print(f"Meshcat viewer: {server.web_url} (server PID {server.pid}, loopback only)", file=out, flush=True)
        if hold_s is None:
            print("Press Ctrl-C to stop.", file=out, flush=True)
        deadline = math.inf if hold_s is None else time.monotonic() + hold_s
        while time.monotonic() < deadline:
            if not server.running:
                raise ViewerError("the Meshcat server process exited while serving")
            time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))
    except KeyboardInterrupt:
        pass
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
