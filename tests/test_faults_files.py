"""Faults found by trying the file readers and the live viewer, one case per row and variant: recordings
(``Recording.load`` / ``falcon-rl replay``) whose array headers or metadata break the schema, ACMI files
that are large in objects x frames or malformed, and idle connections to the Tacview real-time host."""

from __future__ import annotations

import io
import json
import re
import socket
import time
import tracemalloc
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from numpy.lib import format as npy_format

from falcon_rl.bridges.tacview import TacviewServer, client_handshake
from falcon_rl.cli import main
from falcon_rl.recording import MAX_META_DEPTH, RECORDING_FORMAT, Recording, RecordingError
from falcon_rl.viz.acmi import read_acmi

FRAMES, ENVS = 4, 2
META = {"format": RECORDING_FORMAT, "airframe": "volantex_ranger", "dt": 0.1}


# ------------------------------------------------------------------------------- recording files
def npy(array: np.ndarray) -> bytes:
    """The .npy bytes of ``array`` (objects pickled, as a hostile writer could)."""
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=True)
    return buffer.getvalue()


def npy_header(shape: tuple[int, ...], descr: object = "<f4", version: tuple[int, int] = (1, 0)) -> bytes:
    """A .npy header alone (no data) declaring ``shape`` and ``descr``."""
    buffer = io.BytesIO()
    npy_format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False, "shape": shape})
    data = buffer.getvalue()
    return data[:6] + bytes(version) + data[8:]


def meta_bytes(meta: object) -> bytes:
    return npy(np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8))


def members(**overrides: bytes | None) -> dict[str, bytes]:
    """The members of a valid recording of FRAMES x ENVS, with ``overrides`` ({member without .npy:
    bytes, or None to drop it}; ``field__x`` stands for ``field/x``)."""
    quaternion = np.zeros((FRAMES, ENVS, 4), np.float32)
    quaternion[..., 0] = 1.0
    base = {"time": npy(np.arange(FRAMES) * 0.1), "meta": meta_bytes(META),
            "field/position_ned": npy(np.zeros((FRAMES, ENVS, 3), np.float32)),
            "field/quaternion": npy(quaternion)}
    for name, data in overrides.items():
        base[name.replace("__", "/")] = data
    return {name: data for name, data in base.items() if data is not None}


def write_npz(path: Path, content: dict[str, bytes], compresslevel: int = 1) -> Path:
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=compresslevel) as archive:
        for name, data in content.items():
            archive.writestr(name + ".npy", data)
    return path


def zeros_bomb(path: Path, megabytes: int) -> Path:
    """A recording whose field ``quaternion`` declares and holds ``megabytes`` MiB of zeros (a tiny
    compressed file) with a frame count that disagrees with ``time``."""
    content = members(field__quaternion=None)
    write_npz(path, content)
    rows = megabytes * 1024 * 1024 // (4 * 4)
    with zipfile.ZipFile(path, "a", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as archive, \
            archive.open("field/quaternion.npy", "w", force_zip64=True) as stream:
        stream.write(npy_header((rows, 1, 4)))
        chunk = bytes(1024 * 1024)
        for _ in range(megabytes):
            stream.write(chunk)
    return path


def _meta(**fields: object) -> dict[str, bytes]:
    return members(meta=meta_bytes({**META, **fields}))


#: (case, members of the file, what the one-line error must say: field and constraint).
HEADER_CASES: list[tuple[str, dict[str, bytes], str]] = [
    ("4 TiB declared in a 300-byte file", members(time=npy_header((2**40,), "<f8")),
     r"time: the zip member holds \d+ bytes, its \.npy header declares 8796093022\d+"),
    ("field shorter than its header", members(field__position_ned=npy_header((FRAMES, ENVS, 3))),
     r"field 'position_ned': the zip member holds \d+ bytes, its \.npy header declares"),
    ("trailing bytes after the array", members(
        field__position_ned=npy(np.zeros((FRAMES, ENVS, 3), np.float32)) + bytes(100)),
     r"field 'position_ned': the zip member holds \d+ bytes"),
    ("object dtype (a pickle)", members(field__extra=npy(np.array([[object()] * ENVS] * FRAMES))),
     r"field 'extra' has dtype object, expected bool, integer or float"),
    ("complex dtype", members(field__extra=npy(np.zeros((FRAMES, ENVS), np.complex64))),
     r"field 'extra' has dtype complex64, expected bool, integer or float"),
    ("structured dtype", members(field__extra=npy(np.zeros((FRAMES, ENVS), [("a", "<f4")]))),
     r"field 'extra' has dtype .*, expected bool, integer or float"),
    ("negative declared shape", members(field__extra=npy_header((-5, ENVS))),
     r"field 'extra' declares the negative shape \(-5, 2\)"),
    ("npy version 3", members(field__extra=npy_header((FRAMES, ENVS), version=(3, 0))),
     r"field 'extra' is a \.npy file of version \(3, 0\), expected 1\.0 or 2\.0"),
    ("not a .npy member", members(field__extra=b"hello, world"),
     r"field 'extra' is not a \.npy array"),
    ("position with 5 components", members(field__position_ned=npy(np.zeros((FRAMES, ENVS, 5), np.float32))),
     r"field 'position_ned' has shape \[T, E, 5\], expected \[T, E, 3\]"),
    ("no frames", members(time=npy(np.zeros(0)), field__position_ned=npy(np.zeros((0, ENVS, 3))),
                          field__quaternion=npy(np.zeros((0, ENVS, 4)))),
     r"time has 0 frames, a recording file needs at least 1"),
    ("no aircraft", members(field__position_ned=npy(np.zeros((FRAMES, 0, 3))),
                            field__quaternion=npy(np.zeros((FRAMES, 0, 4)))),
     r"field 'position_ned' has no aircraft"),
    ("infinite time", members(time=npy(np.array([0.0, 1.0, 2.0, np.inf]))), r"time must be finite"),
    ("meta as float", members(meta=npy(np.zeros(3))), r"meta must be a \[bytes\] uint8 array"),
    ("meta over 1 MiB", members(meta=meta_bytes({**META, "notes": "x" * (1024 * 1024)})),
     r"meta holds \d+ bytes, at most 1048576 allowed"),
]

#: (case, members of the file, what the one-line error must say).
META_CASES: list[tuple[str, dict[str, bytes], str]] = [
    ("100 k-deep nesting", members(meta=npy(np.frombuffer(
        b'{"format": "%s", "x": ' % RECORDING_FORMAT.encode() + b"[" * 100_000 + b"]" * 100_000 + b"}",
        np.uint8))), rf"meta is nested more than {MAX_META_DEPTH} levels deep"),
    ("40-deep nesting", _meta(notes=json.loads("[" * 40 + "]" * 40)),
     rf"meta is nested more than {MAX_META_DEPTH} levels deep"),
    ("meta a list", members(meta=meta_bytes([1, 2])), r"meta must be a JSON object, got list"),
    ("labels a number", _meta(labels=5),
     r"meta\.labels must be a list of one string per aircraft \(2 aircraft\), got 5"),
    ("labels too few", _meta(labels=["a"]), r"meta\.labels must be a list of one string per aircraft"),
    ("labels not strings", _meta(labels=[1, 2]), r"meta\.labels must be a list of one string"),
    ("dt a word", _meta(dt="fast"), r"meta\.dt must be a finite number of seconds > 0, got 'fast'"),
    ("dt negative", _meta(dt=-0.1), r"meta\.dt must be a finite number of seconds > 0"),
    ("dt NaN", members(meta=npy(np.frombuffer(b'{"format": "%s", "dt": NaN}' % RECORDING_FORMAT.encode(),
                                              np.uint8))), r"meta\.dt must be a finite"),
    ("airframe a list", _meta(airframe=[1, 2]),
     r"meta\.airframe must be an airframe name \(a string\) or null"),
    ("task a number", _meta(task=3), r"meta\.task must be a string or null"),
    ("seed a word", _meta(seed="x"), r"meta\.seed must be an integer or null"),
    ("seed a bool", _meta(seed=True), r"meta\.seed must be an integer or null"),
    ("env_ids negative", _meta(env_ids=[-1]), r"meta\.env_ids must be a list of non-negative integers"),
    ("termination_reasons a number", _meta(termination_reasons=3),
     r"meta\.termination_reasons must be a list of strings"),
    ("every zero", _meta(every=0), r"meta\.every must be an integer >= 1"),
    ("not UTF-8", members(meta=npy(np.frombuffer(b"\xff\xfe", np.uint8))),
     r"meta is not a UTF-8 JSON document"),
]


@pytest.mark.parametrize(("case", "content", "message"), HEADER_CASES + META_CASES,
                         ids=[case for case, _, _ in HEADER_CASES + META_CASES])
def test_bad_recording_is_one_line_naming_file_field_constraint(tmp_path, case, content, message):
    path = write_npz(tmp_path / "bad.npz", content)
    with pytest.raises(RecordingError) as raised:
        Recording.load(path)
    text = str(raised.value)
    assert "\n" not in text and text.startswith(f"{path}: ")
    assert re.search(message, text), text


@pytest.mark.parametrize("case", ["4 TiB declared in a 300-byte file", "100 k-deep nesting",
                                  "labels a number"])
def test_replay_refuses_in_one_line_exit_2(tmp_path, capsys, case):
    content = dict((c, m) for c, m, _ in HEADER_CASES + META_CASES)[case]
    path = write_npz(tmp_path / "bad.npz", content)
    assert main(["replay", str(path), "--acmi", str(tmp_path / "out.acmi")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"falcon-rl replay: error: {path}: ") and "\n" not in err
    assert not (tmp_path / "out.acmi").exists()


def test_a_field_of_zeros_is_refused_before_it_is_read(tmp_path):
    path = zeros_bomb(tmp_path / "zeros.npz", megabytes=64)
    assert path.stat().st_size < 1024 * 1024  # 64 MiB of zeros compress to a tiny file
    tracemalloc.start()
    try:
        with pytest.raises(RecordingError,
                           match=r"field 'quaternion' has shape \(4194304, 1, 4\), expected \[4, 2"):
            Recording.load(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 8 * 1024 * 1024, f"{peak / 2**20:.0f} MiB allocated to refuse the file"


def test_max_bytes_is_checked_from_the_headers(tmp_path):
    path = write_npz(tmp_path / "ok.npz", members())
    assert Recording.load(path).num_envs == ENVS
    with pytest.raises(RecordingError, match=r"ok\.npz: the arrays declare \d+ bytes, more than the 100 "):
        Recording.load(path, max_bytes=100)


# ----------------------------------------------------------------------------------------- ACMI
HEADER = "FileType=text/acmi/tacview\nFileVersion=2.2\n"


def acmi_text(objects: int, frames: int) -> str:
    """``objects`` aircraft placed once, then ``frames`` frames in which nothing changes."""
    lines = ["#0", *(f"{0x100 + k:x},T=0|0|{k}" for k in range(objects)),
             *(f"#{k}" for k in range(1, frames))]
    return HEADER + "\n".join(lines) + "\n"


def peak_read_bytes(path: Path) -> int:
    tracemalloc.start()
    try:
        read_acmi(path)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_reading_is_linear_in_what_the_file_holds(tmp_path):
    big = tmp_path / "big.acmi"
    big.write_text(acmi_text(2000, 2000))
    reference = tmp_path / "reference.acmi"  # the same objects, 2 frames: about as many lines and bytes
    reference.write_text(acmi_text(2000, 2))
    assert big.stat().st_size < 50_000
    peak, reference_peak = peak_read_bytes(big), peak_read_bytes(reference)
    assert peak < 2 * reference_peak, f"{peak / 2**20:.1f} MiB vs {reference_peak / 2**20:.1f} MiB"
    parsed = read_acmi(big)
    assert len(parsed.objects) == 2000 and len(parsed.frames) == 2000
    track = parsed.objects[format(0x100 + 1999, "x")]
    assert track.num_frames == 2000
    np.testing.assert_array_equal(track.altitude, np.full(2000, 1999.0))
    np.testing.assert_array_equal(track.time, np.arange(2000.0))


#: (case, file name, content, the error after the file name).
ACMI_CASES: list[tuple[str, str, bytes, str]] = [
    ("zip that is not a zip", "bad.zip.acmi", b"PK\x03\x04 not a zip", r": not a readable zip archive"),
    ("empty file", "empty.acmi", b"", r", line 1: not an ACMI file"),
    ("no FileVersion", "short.acmi", b"FileType=text/acmi/tacview\nhello\n", r", line 2: not an ACMI file"),
    ("bad T component", "t.acmi", (HEADER + "#0\n101,T=1|x|3\n").encode(),
     r", line 4: bad T component lat 'x' \(expected a number\)"),
    ("bad frame time", "frame.acmi", (HEADER + "#0\n#soon\n").encode(), r", line 4: bad frame time 'soon'"),
    ("bad object id", "id.acmi", (HEADER + "#0\nzz,T=1|2|3\n").encode(), r", line 4: bad object id 'zz'"),
    ("T of 2 components", "two.acmi", (HEADER + "#0\n101,T=1|2\n").encode(),
     r", line 4: T has 2 components, expected 3, 5, 6 or 9"),
    ("bad reference longitude", "ref.acmi", (HEADER + "0,ReferenceLongitude=east\n").encode(),
     r", line 3: bad ReferenceLongitude 'east'"),
    ("line after a continued line", "cont.acmi", (HEADER + "0,Comments=a\\\nb\n#0\n101,T=1|2|x\n").encode(),
     r", line 6: bad T component alt 'x'"),
    ("not UTF-8", "latin.acmi", (HEADER + "#0\n").encode() + b"101,Name=caf\xe9\n",
     r", line 4: not UTF-8 text"),
]


@pytest.mark.parametrize(("case", "name", "content", "message"), ACMI_CASES, ids=[c[0] for c in ACMI_CASES])
def test_bad_acmi_is_one_line_value_error_naming_file_and_line(tmp_path, case, name, content, message):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ValueError) as raised:
        read_acmi(path)
    text = str(raised.value)
    assert "\n" not in text and text.startswith(str(path))
    assert re.search(message, text), text


def test_zipped_acmi_errors_name_the_member_and_line(tmp_path):
    path = tmp_path / "flight.zip.acmi"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("flight.txt.acmi", HEADER + "#0\n101,T=1|2|high\n")
    with pytest.raises(ValueError, match=r"flight\.zip\.acmi\[flight\.txt\.acmi\], line 4: bad T comp"):
        read_acmi(path)


# ------------------------------------------------------------------------------------- Tacview
def _closed(sock: socket.socket) -> bool:
    """Whether the server closed ``sock`` (its greeting, if any, is read and dropped)."""
    try:
        while True:
            chunk = sock.recv(4096)
            if not chunk:
                return True
    except (BlockingIOError, TimeoutError):
        return False
    except OSError:
        return True


def _poll_until(server: TacviewServer, done: Callable[[], bool], seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        server.poll()
        if done():
            return True
        time.sleep(0.01)
    return done()


@pytest.mark.parametrize(("idle", "max_clients"), [(3, 4), (40, 4)], ids=["under the cap", "over the cap"])
def test_idle_connections_are_closed_and_a_real_client_is_served(idle, max_clients):
    timeout = 0.3
    with TacviewServer(port=0, handshake_timeout=timeout, max_clients=max_clients) as server:
        sockets = [socket.create_connection((server.host, server.port), timeout=2.0) for _ in range(idle)]
        try:
            for sock in sockets:
                sock.setblocking(False)
            started = time.monotonic()
            _poll_until(server, lambda: server.num_connections >= min(idle, max_clients), 1.0)
            assert server.num_connections <= max_clients
            over = [s for s in sockets if _closed(s)]  # closed at once: beyond the cap
            assert len(over) >= idle - max_clients
            assert _poll_until(server, lambda: all(_closed(s) for s in sockets), 10 * timeout)
            assert server.num_connections == 0 and time.monotonic() - started >= timeout
        finally:
            for sock in sockets:
                sock.close()
        with socket.create_connection((server.host, server.port), timeout=2.0) as client:
            assert _poll_until(server, lambda: server.num_connections == 1, 2.0)
            client.sendall(client_handshake("pytest"))
            assert _poll_until(server, lambda: server.num_clients == 1, 2.0)
            time.sleep(2 * timeout)  # past the handshake deadline: a client that shook hands stays
            assert server.send_frame(0.0, np.zeros((1, 3)), np.zeros((1, 3))) == 1
            client.settimeout(2.0)
            data = b""
            while b"#0\n" not in data and len(data) < 65536:
                chunk = client.recv(4096)
                if not chunk:
                    break
                data += chunk
            assert b"#0\n" in data


@pytest.mark.parametrize(("options", "message"), [
    ({"handshake_timeout": 0.0}, "handshake_timeout"),
    ({"handshake_timeout": float("inf")}, "handshake_timeout"),
    ({"max_clients": 0}, "max_clients"), ({"max_clients": True}, "max_clients")])
def test_tacview_limits_are_checked(options, message):
    with pytest.raises(ValueError, match=message):
        TacviewServer(port=0, **options)
