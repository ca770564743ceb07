"""--connect and --serve-web (Rerun's example conventions): where the stream goes, and serving until Ctrl-C."""

from __future__ import annotations

import socket
import threading
import urllib.request
from pathlib import Path

import pytest
import rerun as rr

from isf_robot.record import stream as st
from isf_robot.record.errors import RecordError
from isf_robot.record.replay import read_rrd

pytestmark = pytest.mark.usefixtures("arm_compiled")  # (compiled before a clock starts: tests/conftest.py)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_connect_streams_to_the_given_address(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """A listener at the address receives the start of a gRPC (HTTP/2) connection. It is no viewer and
    hangs up: the run says so in one line (exit 2) and the recording file is still completed."""
    from isf_robot.cli import main

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    srv.settimeout(30)
    got = bytearray()

    def accept() -> None:
        try:
            conn, _ = srv.accept()
            conn.settimeout(5)
            got.extend(conn.recv(64))
            conn.close()
        except OSError:
            pass

    th = threading.Thread(target=accept, daemon=True)
    th.start()
    url = f"rerun+http://127.0.0.1:{srv.getsockname()[1]}/proxy"
    out = tmp_path / "run.rrd"
    code = main(["run", "--scene", "planar", "--duration", "0.2", "--connect", url, "--rrd", str(out)])
    th.join(30)
    srv.close()
    assert bytes(got).startswith(b"PRI * HTTP/2.0")
    err = capsys.readouterr().err
    assert code == 2 and "connection to the Rerun viewer failed" in err and "disk full" not in err
    assert read_rrd(out)[0].steps["t"].size == 100 and not Path(str(out) + ".partial").exists()


def test_bad_connect_address_is_one_line(capsys) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    assert main(["run", "--scene", "planar", "--duration", "0.2", "--connect", "localhost:9876"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "rerun+http://HOST:PORT/proxy" in err


def test_serve_web_serves_the_page_and_waits_for_ctrl_c(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    grpc, web = _free_port(), _free_port()
    rec = st.open_stream("isf_robot_test", rrd_path=tmp_path / "x.rrd", serve_web=True, grpc_port=grpc, web_port=web)
    try:
        assert f"127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy" in capsys.readouterr().err
        with pytest.raises(RecordError, match="one recording per process"):
            st.open_stream("isf_robot_test", serve_web=True, grpc_port=_free_port(), web_port=_free_port())
        rec.log("/x", rr.Scalars(1.0))
        assert st.close_stream(rec) == tmp_path / "x.rrd"  # the file is complete, the server stays up
        with urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=10) as page:
            assert page.status == 200 and b"<html" in page.read(4096).lower()
        naps: list[float] = []

        def sleep(s: float) -> None:
            naps.append(s)
            if len(naps) == 3:
                raise KeyboardInterrupt  # the user's Ctrl-C

        assert st.wait_while_serving(sleep=sleep) is True and len(naps) == 3
        assert "press Ctrl-C to stop" in capsys.readouterr().err
        assert st.wait_while_serving(sleep=sleep) is False  # nothing served any more
    finally:
        while st._SERVING:
            st._SERVING.pop()[2].stop()


def _listening(ports: set[int]) -> dict[int, str]:
    """Address of the listening TCP (IPv4) sockets on ``ports``, read from /proc/net/tcp."""
    out = {}
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        fields = line.split()
        local, state = fields[1], fields[3]
        addr_hex, port_hex = local.split(":")
        port = int(port_hex, 16)
        if state == "0A" and port in ports:  # 0A: LISTEN
            out[port] = socket.inet_ntoa(bytes.fromhex(addr_hex)[::-1])
    return out


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads Linux's /proc/net/tcp")
@pytest.mark.parametrize(("extra", "address"), [((), "127.0.0.1"), (("--bind", "0.0.0.0"), "0.0.0.0")])
def test_serve_web_listens_where_asked_and_stops_on_ctrl_c(extra: tuple[str, ...], address: str) -> None:
    """A real `isf-robot run --serve-web`: both servers (the page, served by a `rerun` child, and the
    recording's gRPC server) listen on 127.0.0.1 unless --bind; Ctrl-C ends both, exit 0."""
    import os
    import signal
    import subprocess
    import sys
    import time

    web, grpc = _free_port(), _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "isf_robot.cli", "run", "--scene", "planar", "--duration", "0.2",
                             "--serve-web", "--web-port", str(web), "--grpc-port", str(grpc), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert proc.stderr is not None
        lines = []
        while not any("press Ctrl-C" in ln for ln in lines):
            line = proc.stderr.readline()
            assert line, "".join(lines)
            lines.append(line)
        assert _listening({web, grpc}) == {web: address, grpc: address}, "".join(lines)
        page = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy"
        assert page in "".join(lines)
        with urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=10) as reply:
            assert reply.status == 200
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0 and "Traceback" not in err, err
    t0 = time.monotonic()
    while _listening({web, grpc}) and time.monotonic() - t0 < 10:  # the `rerun` child went with it
        time.sleep(0.1)
    assert _listening({web, grpc}) == {}


@pytest.mark.parametrize(("argv", "says"), [
    (["--serve-web", "--bind", "localhost"], "valid: 127.0.0.1"),
    (["--serve-web", "--bind", "1.2.3.4.5"], "not an IP address"),
    (["--bind", "0.0.0.0"], "add --serve-web"),
    (["--serve-web", "--web-port", "70000"], "1..65535"),
    (["--serve-web", "--web-port", "9999", "--grpc-port", "9999"], "must differ"),
])
def test_bad_serve_options_are_one_line(argv: list[str], says: str, capsys) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    assert main(["run", "--scene", "planar", "--duration", "0.2", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and says in err, err


def test_a_taken_web_port_is_one_line(capsys) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        assert main(["run", "--scene", "planar", "--duration", "0.2", "--serve-web", "--web-port", str(port),
                     "--grpc-port", str(_free_port())]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"port {port}" in err and "web viewer" in err, err
    assert not st._SERVING
