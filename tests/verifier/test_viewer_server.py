"""The viewer's Meshcat server: loopback only, stopped by PID, and Meshcat kept out of the
modules that do not draw.

meshcat 0.3.2's web server listens on every interface; ours must listen on 127.0.0.1 only
(both the ZeroMQ and the web port), checked here from /proc for the server's PID. After
shutdown (context exit, SIGTERM to the CLI, or interpreter exit) the process must be gone.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import pytest

from verify.viewer.server import (
    ListeningSocket,
    MeshcatServer,
    ServerConfig,
    ViewerError,
    _decode_address,
    listening_sockets,
)

ROOT = Path(__file__).resolve().parents[2]
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def gone(pid: int, timeout_s: float = 10.0) -> bool:
    """True once no process (not even a zombie) has this PID, within the timeout [s]."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        status = Path(f"/proc/{pid}/status")
        try:
            text = status.read_text()
        except FileNotFoundError:
            return True
        if re.search(r"^State:\s+Z", text, re.MULTILINE):
            return False  # a zombie: its parent did not wait for it
        time.sleep(0.05)
    return False


def assert_loopback_only(pid: int, ports: set[int]) -> None:
    sockets = listening_sockets(pid)
    assert sockets, f"process {pid} listens on nothing"
    assert all(s.address == "127.0.0.1" for s in sockets), sockets
    assert {s.port for s in sockets} == ports, sockets


@linux_only
def test_server_listens_on_loopback_only_and_is_gone_after_stop():
    with MeshcatServer() as server:
        pid = server.pid
        assert server.running
        assert server.web_url.startswith("http://127.0.0.1:")
        assert server.zmq_url.startswith("tcp://127.0.0.1:")
        assert_loopback_only(pid, {server.zmq_port, server.web_port})
        # It serves the viewer (a local request, no network).
        with urllib.request.urlopen(server.web_url, timeout=10) as response:
            assert response.status == 200
            assert b"MeshCat" in response.read()
        # A client can draw through it.
        vis = server.visualizer()
        vis["box"].set_transform()
    assert not server.running
    assert gone(pid)


@linux_only
def test_live_cli_serves_on_loopback_and_stops_its_server_on_sigterm():
    cli = subprocess.Popen(
        [sys.executable, "-m", "verify.view", "--paper-test1", "--hold", "120"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = cli.stdout.readline()
        match = re.match(r"Meshcat viewer: http://127\.0\.0\.1:(\d+)/static/ \(server PID (\d+), loopback only\)", line)
        assert match, (line, cli.stderr.read() if cli.poll() is not None else "")
        web_port, server_pid = int(match[1]), int(match[2])
        sockets = listening_sockets(server_pid)
        assert web_port in {s.port for s in sockets}
        assert len(sockets) == 2 and all(s.address == "127.0.0.1" for s in sockets), sockets
        cli.send_signal(signal.SIGTERM)
        out, err = cli.communicate(timeout=30)
    finally:
        if cli.poll() is None:
            cli.kill()
            cli.wait()
    assert cli.returncode == 0, err
    assert "stopped the Meshcat server" in out
    assert gone(server_pid)


@linux_only
def test_server_is_stopped_at_interpreter_exit():
    code = "from verify.viewer.server import MeshcatServer; print(MeshcatServer().start().pid, flush=True)"
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert gone(int(done.stdout.strip()))


def test_stop_is_idempotent_and_a_stopped_server_refuses_clients():
    server = MeshcatServer().start()
    server.stop()
    server.stop()
    with pytest.raises(ViewerError, match="not running"):
        server.visualizer()


@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.1.10", "::", "::1", "localhost", ""])
def test_config_refuses_non_loopback_hosts(host):
    with pytest.raises(ViewerError, match="loopback"):
        ServerConfig(host=host)


def test_config_accepts_ipv4_loopback():
    assert ServerConfig().host == "127.0.0.1"
    assert ServerConfig(host="127.0.0.2").host == "127.0.0.2"


@pytest.mark.parametrize(
    ("hex_address", "expected"),
    [
        ("0100007F", "127.0.0.1"),
        ("00000000", "0.0.0.0"),
        ("0101A8C0", "192.168.1.1"),
        ("00000000000000000000000001000000", "::1"),
        ("00000000000000000000000000000000", "::"),
    ],
)
def test_proc_net_addresses_are_decoded(hex_address, expected):
    assert _decode_address(hex_address) == expected


def test_wildcard_addresses_are_not_loopback():
    assert ListeningSocket("127.0.0.1", 7000).is_loopback
    assert ListeningSocket("::1", 7000).is_loopback
    assert not ListeningSocket("0.0.0.0", 7000).is_loopback
    assert not ListeningSocket("::", 7000).is_loopback


@linux_only
def test_listening_sockets_of_a_missing_process_raise():
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    with pytest.raises(ViewerError):
        listening_sockets(child.pid)


def test_meshcat_is_imported_only_by_the_viewer_modules():
    """At run time too: importing every other module of both packages (and the viewer's server and
    browser helpers, which draw nothing) loads no Meshcat module."""
    modules = []
    for package in ("pipeline", "verify"):
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] in {"__init__", "__main__"}:
                parts.pop()
            name = ".".join(parts)
            if name == "pipeline.generate":  # the -m entry point, which refuses to be imported
                continue
            if not name.startswith("verify.viewer.") or name in {"verify.viewer.server", "verify.viewer.browser"}:
                modules.append(name)
    code = (
        "import importlib, sys\n"
        f"for name in {modules!r}:\n"
        "    importlib.import_module(name)\n"
        "loaded = sorted(m for m in sys.modules if m == 'meshcat' or m.startswith('meshcat.'))\n"
        "print(loaded)\n"
    )
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_sigterm_is_handled_before_the_url_is_announced():
    """Whoever reads the URL may send SIGTERM at once: the handler must already be in place when
    the line is written (it was not, and the live CLI died with -15 now and then)."""
    from verify.viewer.server import serve_until_interrupted

    class FakeServer:
        web_url, pid, running = "http://127.0.0.1:7000/static/", 1, True

    class Recorder:
        def __init__(self) -> None:
            self.handlers: list[object] = []

        def write(self, text: str) -> int:
            if text.startswith("Meshcat viewer"):
                handler = signal.getsignal(signal.SIGTERM)
                self.handlers.append(handler)
                if handler in (signal.SIG_DFL, signal.SIG_IGN, None):
                    raise AssertionError("the URL is announced before SIGTERM is handled")
                os.kill(os.getpid(), signal.SIGTERM)  # as the test above does on reading the line
            return len(text)

        def flush(self) -> None:
            pass

    before = signal.getsignal(signal.SIGTERM)
    out = Recorder()
    serve_until_interrupted(FakeServer(), hold_s=30.0, out=out)  # returns at once: SIGTERM stops it cleanly
    assert out.handlers and out.handlers[0] not in (signal.SIG_DFL, signal.SIG_IGN, None)
    assert signal.getsignal(signal.SIGTERM) == before


def test_reading_the_log_leaves_the_shared_file_offset_alone(tmp_path):
    """The server process writes its log through the same open file as ours (one shared offset):
    reading it must not seek, or the next line it writes could overwrite the first (a lost URL
    line, seen as a 30 s start timeout once in 20 suite runs)."""
    server = MeshcatServer()
    log = tempfile.TemporaryFile()
    server._log = log
    try:
        log.write(b"zmq_url=tcp://127.0.0.1:6000\n")
        log.flush()
        written_up_to = log.tell()
        assert server._read_log() == "zmq_url=tcp://127.0.0.1:6000\n"
        assert log.tell() == written_up_to  # the writer's next line goes after its first
        log.write(b"web_url=http://127.0.0.1:7000/static/\n")
        log.flush()
        log.seek(5)  # wherever the writer's offset is, reading neither needs nor moves it
        assert server._read_log().splitlines() == [
            "zmq_url=tcp://127.0.0.1:6000",
            "web_url=http://127.0.0.1:7000/static/",
        ]
        assert log.tell() == 5
    finally:
        server._log = None
        log.close()
