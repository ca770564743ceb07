"""Viewer addresses: where ``--serve-web`` listens (bind address, ports, the page) and ``--connect`` streams.

``--serve-web`` needs two servers: the recording's gRPC server (a
:class:`rerun.GrpcServerSink`, which takes a bind address) and the web viewer's page. The
Python SDK's :func:`rerun.serve_web_viewer` (rerun-sdk 0.41) takes no bind address and listens
on every interface (``0.0.0.0``), so the page is served instead by the ``rerun`` executable that
ships with rerun-sdk, in a child process: ``rerun --serve-web --bind ADDR --web-viewer-port PORT
URL`` (given a URL it hosts the page only, pointing the viewer at that gRPC server, and opens
no browser). The child runs in its own session (Ctrl-C at the terminal reaches only this
process, which then stops it); on Linux it also gets SIGTERM when this process dies.

By default both servers listen on ``127.0.0.1`` (this machine only); ``--bind ADDR`` exposes
them on another address (``0.0.0.0``: every interface).
"""

from __future__ import annotations

import atexit
import ipaddress
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .errors import RecordError

__all__ = ["DEFAULT_BIND", "DEFAULT_CONNECT", "GRPC_PORT", "WEB_PORT", "check_bind", "check_port_free", "connect_host",
           "rerun_binary", "rerun_executable", "WebViewerServer"]

DEFAULT_BIND = "127.0.0.1"
"""Address ``--serve-web`` listens on without ``--bind``: this machine only."""
GRPC_PORT = 9876
"""Port of the gRPC server of ``--serve-web``."""
WEB_PORT = 9090
"""Port of the web viewer's page of ``--serve-web``."""
DEFAULT_CONNECT = "rerun+http://127.0.0.1:9876/proxy"
"""Where ``--connect`` streams without an address: a viewer started with ``rerun`` on this machine."""
START_TIMEOUT_S = 20.0
"""How long the web viewer's server may take to listen."""


def check_bind(addr: str) -> str:
    """The address ``--bind`` names, checked: an IPv4 or IPv6 address (no host names, no port).

    Raises:
        RecordError: Not an IP address (one line naming the valid forms).

    """
    try:
        return str(ipaddress.ip_address(str(addr).strip().strip("[]")))
    except ValueError:
        raise RecordError(f"--bind {addr!r}: not an IP address; valid: 127.0.0.1 (default, this machine only), "
                          "0.0.0.0 (every interface), :: (every interface, IPv6) or one address of this "
                          "machine") from None


def connect_host(bind: str) -> str:
    """Host part of the URLs to reach a server bound to ``bind`` (loopback for an unspecified address)."""
    ip = ipaddress.ip_address(bind)
    if ip.is_unspecified:
        return "127.0.0.1"
    return f"[{ip}]" if ip.version == 6 else str(ip)


def rerun_executable() -> Path | None:
    """The ``rerun`` executable of rerun-sdk (on ``PATH`` or beside the Python interpreter), or ``None``."""
    found = shutil.which("rerun")
    exe = Path(found) if found else Path(sys.executable).parent / ("rerun.exe" if os.name == "nt" else "rerun")
    return exe if exe.is_file() else None


def rerun_binary() -> Path | None:
    """The ``rerun`` program itself, not the Python launcher on ``PATH`` that starts it as its child.

    The launcher (rerun-sdk's ``rerun`` entry point, :mod:`rerun_cli`) runs the binary shipped in
    the :mod:`rerun_cli` package (or ``RERUN_CLI_PATH``); stopping the launcher would leave the
    binary serving. Falls back to :func:`rerun_executable`.
    """
    override = os.environ.get("RERUN_CLI_PATH")
    if override and Path(override).is_file():
        return Path(override)
    try:
        import rerun_cli
    except ImportError:
        return rerun_executable()
    folder = Path(rerun_cli.__file__).parent
    suffix = ".exe" if sys.platform.startswith("win") else ""
    for candidate in (folder / "Rerun.app" / "Contents" / "MacOS" / "Rerun", folder / f"rerun{suffix}"):
        if candidate.is_file():
            return candidate
    return rerun_executable()


def check_port_free(bind: str, port: int, what: str) -> None:
    """Fail with one line when ``bind:port`` cannot be listened on (taken, or not an address of this machine)."""
    family = socket.AF_INET6 if ipaddress.ip_address(bind).version == 6 else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((bind, int(port)))
        except OSError as exc:
            raise RecordError(f"--serve-web cannot serve {what} on {bind} port {port}: "
                              f"{exc.strerror or exc}") from None


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass


class WebViewerServer:
    """Rerun's web viewer page on ``bind:port``, served by a ``rerun`` child process.

    Args:
        bind: Checked address (:func:`check_bind`).
        port: TCP port of the page.
        grpc_url: The gRPC server the viewer connects to (``rerun+http://HOST:PORT/proxy``).

    Raises:
        RecordError: No ``rerun`` executable, the port is taken, or the server did not start
            (its last line of output is quoted).

    """

    def __init__(self, bind: str, port: int, grpc_url: str) -> None:
        exe = rerun_binary()
        if exe is None:
            raise RecordError("--serve-web serves the web viewer with rerun-sdk's 'rerun' executable, and none was "
                              f"found on PATH or beside {sys.executable}; reinstall rerun-sdk, or save with --rrd")
        check_port_free(bind, port, "the web viewer")
        self.bind, self.port = bind, int(port)
        self._log = tempfile.TemporaryFile()
        env = dict(os.environ, RUST_LOG=os.environ.get("RUST_LOG", "warn"))
        self.proc: subprocess.Popen[bytes] | None = subprocess.Popen(
            [str(exe), "--serve-web", "--bind", bind, "--web-viewer-port", str(self.port), grpc_url],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=self._log, env=env,
            start_new_session=True, preexec_fn=_die_with_parent if os.name == "posix" else None)
        atexit.register(self.stop)
        self._wait_listening()

    def _wait_listening(self) -> None:
        host = connect_host(self.bind).strip("[]")
        t0 = time.monotonic()
        while time.monotonic() - t0 < START_TIMEOUT_S:
            assert self.proc is not None
            if self.proc.poll() is not None:
                why = self._last_line() or f"exit status {self.proc.returncode}"
                self.stop()
                raise RecordError(f"--serve-web: the web viewer's server stopped at once: {why}")
            try:
                with socket.create_connection((host, self.port), timeout=0.5):
                    return
            except OSError:
                time.sleep(0.1)
        self.stop()
        raise RecordError(f"--serve-web: the web viewer's server did not listen on {self.bind} port {self.port} "
                          f"within {START_TIMEOUT_S:g} s")

    def _last_line(self) -> str:
        self._log.seek(0)
        lines = [ln.strip() for ln in self._log.read().decode("utf-8", "replace").splitlines() if ln.strip()]
        return " ".join(lines[-1].split()) if lines else ""

    @staticmethod
    def _signal(proc: subprocess.Popen[bytes], sig: int) -> None:
        """Signal the child's process group (its session: anything it started too), else the child."""
        try:
            if os.name == "posix":
                os.killpg(proc.pid, sig)
            else:
                proc.send_signal(sig)
        except (ProcessLookupError, PermissionError):
            pass

    def stop(self) -> None:
        """Stop the child (SIGTERM, then SIGKILL after 5 s); safe to call again."""
        proc, self.proc = self.proc, None
        if proc is not None and proc.poll() is None:
            self._signal(proc, signal.SIGTERM)
            try:
                proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self._signal(proc, signal.SIGKILL if os.name == "posix" else signal.SIGTERM)
                proc.wait()
        if not self._log.closed:
            self._log.close()
        atexit.unregister(self.stop)
