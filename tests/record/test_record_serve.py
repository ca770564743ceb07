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
        st._SERVING.clear()
