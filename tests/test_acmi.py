"""Geodesy, the Tacview ACMI exporter and parser, and the Tacview real-time telemetry host."""

from __future__ import annotations

import re
import socket
import time
import zipfile
from datetime import datetime, timezone

import numpy as np
import pytest
import torch

import falcon_rl
from falcon_rl.bridges.tacview import TacviewServer, client_handshake, password_hashes
from falcon_rl.recording import Recording, record_simulator
from falcon_rl.viz.acmi import parse_acmi, read_acmi, write_acmi
from falcon_rl.viz.geodesy import (
    WGS84_A,
    WGS84_E2,
    ReferencePoint,
    euler_from_local_level,
    euler_to_local_level,
    geodetic_to_ned,
    ned_to_geodetic,
)

WHEN = datetime(2024, 5, 17, 9, 30, 0, tzinfo=timezone.utc)


@pytest.fixture(scope="module")
def recording() -> Recording:
    sim = falcon_rl.Simulator(falcon_rl.load_airframe("volantex_ranger"), num_envs=2, backend="torch")
    sim.reset()
    commands = torch.tensor([[0.1, 0.4, 0.0, 0.7], [-0.1, -0.3, 0.2, 0.5]])
    return record_simulator(sim, commands, steps=40, substeps=2)


def _wrap_deg(angle: np.ndarray) -> np.ndarray:
    return (angle + 180.0) % 360.0 - 180.0


# ---------------------------------------------------------------------------------------- geodesy
@pytest.mark.parametrize("ref", [ReferencePoint(), ReferencePoint(0.0, 0.0, 0.0),
                                 ReferencePoint(-71.5, 179.9, 2500.0), ReferencePoint(89.5, -45.0, 10.0)])
def test_round_trip_below_a_millimetre_over_10_km(ref: ReferencePoint) -> None:
    ned = np.random.default_rng(0).uniform(-10_000.0, 10_000.0, (500, 3))
    lat, lon, alt = ned_to_geodetic(ref, ned)
    assert np.abs(geodetic_to_ned(ref, lat, lon, alt) - ned).max() < 1e-3


def test_one_km_north_at_the_equator() -> None:
    lat, lon, alt = ned_to_geodetic(ReferencePoint(0.0, 0.0, 0.0), np.array([1000.0, 0.0, 0.0]))
    assert lat == pytest.approx(1.0 / 111.2, rel=0.01)  # a degree of latitude is ~111 km
    meridian_radius = WGS84_A * (1.0 - WGS84_E2)  # at the equator
    assert np.radians(lat) == pytest.approx(1000.0 / meridian_radius, rel=1e-6)
    assert lon == pytest.approx(0.0, abs=1e-12)
    assert alt == pytest.approx(1000.0**2 / (2 * meridian_radius), rel=0.01)  # the earth curves away


def test_altitude_is_reference_plus_height() -> None:
    ref = ReferencePoint(47.4647, 8.5492, 432.0)
    for height in (0.0, 3.0, 120.0, 2000.0):
        lat, lon, alt = ned_to_geodetic(ref, np.array([0.0, 0.0, -height]))
        assert alt == pytest.approx(432.0 + height, abs=1e-6)
        assert lat == pytest.approx(47.4647, abs=1e-12) and lon == pytest.approx(8.5492, abs=1e-12)
    _, _, alt = ned_to_geodetic(ref, np.array([10.0, -10.0, -50.0]))
    assert alt == pytest.approx(482.0, abs=1e-4)


def test_local_level_attitude_round_trip() -> None:
    rng = np.random.default_rng(1)
    ned = rng.uniform(-5000.0, 5000.0, (50, 3))
    euler = rng.uniform(-1.2, 1.2, (50, 3))
    local = euler_to_local_level(None, ned, euler)
    assert np.abs(np.degrees(local - euler)).max() < 0.1  # meridian convergence over 5 km
    assert np.abs(euler_from_local_level(None, ned, local) - euler).max() < 1e-12
    at_origin = euler_to_local_level(None, np.zeros((1, 3)), euler[:1])
    assert np.abs(at_origin - euler[:1]).max() < 1e-12


def test_geodesy_bad_inputs() -> None:
    with pytest.raises(ValueError, match="latitude"):
        ReferencePoint(91.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        ReferencePoint(0.0, float("nan"), 0.0)
    with pytest.raises(ValueError, match=r"\[\.\.\., 3\]"):
        ned_to_geodetic(None, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        ned_to_geodetic(None, np.array([0.0, np.inf, 0.0]))
    with pytest.raises(ValueError, match="non-finite"):
        geodetic_to_ned(None, np.nan, 0.0, 0.0)


# ---------------------------------------------------------------------------------------- ACMI files
def _check_track(rec: Recording, parsed, ref: ReferencePoint) -> None:
    assert len(parsed.objects) == rec.num_envs
    for e, track in enumerate(sorted(parsed.objects.values(), key=lambda t: int(t.object_id, 16))):
        np.testing.assert_allclose(track.time, rec.time, atol=1e-6)
        ned = geodetic_to_ned(ref, track.latitude, track.longitude, track.altitude)
        assert np.abs(ned - rec["position_ned"][:, e]).max() < 0.01
        local = np.radians(np.stack([track.roll, track.pitch, track.yaw], axis=-1))
        euler = euler_from_local_level(ref, ned, local)
        error = _wrap_deg(np.degrees(euler) - np.degrees(rec["euler"][:, e].astype(np.float64)))
        assert np.abs(error).max() < 0.01


def test_text_file_header_frames_and_track(recording: Recording, tmp_path) -> None:
    ref = ReferencePoint(47.4647, 8.5492, 432.0)
    path = write_acmi(recording, tmp_path / "flight.txt.acmi", reference=ref, reference_time=WHEN,
                      title="test flight")
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[:2] == ["FileType=text/acmi/tacview", "FileVersion=2.2"]
    assert "0,ReferenceTime=2024-05-17T09:30:00Z" in lines
    assert "0,ReferenceLongitude=8.5492" in lines and "0,ReferenceLatitude=47.4647" in lines
    assert "0,Title=test flight" in lines
    assert re.fullmatch(r"0,ReferenceTime=\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?Z",
                        next(line for line in lines if "ReferenceTime" in line))
    frames = [float(line[1:]) for line in lines if line.startswith("#")]
    assert len(frames) == recording.num_frames and np.all(np.diff(frames) > 0)
    first = next(line for line in lines if line.startswith("101,"))
    assert re.match(r"101,T=[^|,]+\|[^|,]+\|[^|,]+\|[^|,]+\|[^|,]+\|[^|,]+,", first)
    assert "Type=Air+FixedWing" in first and "Name=aircraft 0" in first and "Color=" in first
    later = [line for line in lines if line.startswith("101,")][1:]
    assert any("||" in line for line in later)  # unchanged components are left out
    parsed = read_acmi(path)
    assert parsed.header["FileVersion"] == "2.2" and parsed.header["Title"] == "test flight"
    _check_track(recording, parsed, ref)
    track = parsed.objects["101"]
    np.testing.assert_allclose(track.values["TAS"], recording["airspeed"][:, 0], atol=0.006)
    np.testing.assert_allclose(track.values["AOA"], np.degrees(recording["alpha"][:, 0]), atol=0.006)


def test_zip_file(recording: Recording, tmp_path) -> None:
    path = write_acmi(recording, tmp_path / "flight.zip.acmi", reference_time=WHEN)
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        assert names == ["flight.txt.acmi"]
        content = archive.read(names[0]).decode("utf-8")
        assert content.startswith("FileType=text/acmi/tacview\nFileVersion=2.2\n")
    text = write_acmi(recording, tmp_path / "flight.txt.acmi", reference_time=WHEN)
    assert zipfile.ZipFile(path).read("flight.txt.acmi") == text.read_bytes()
    _check_track(recording, read_acmi(path), ReferencePoint())


def test_many_aircraft_and_names_with_commas(tmp_path) -> None:
    frames, envs = 30, 6
    t = np.arange(frames) * 0.1
    position = np.zeros((frames, envs, 3), np.float32)
    position[..., 0] = 20.0 * t[:, None] + 50.0 * np.arange(envs)
    position[..., 1] = 5.0 * np.arange(envs)
    position[..., 2] = -30.0 - np.arange(envs)
    euler = np.zeros((frames, envs, 3), np.float32)
    euler[..., 0] = 0.3 * np.sin(t)[:, None]
    euler[..., 2] = -2.5 + 0.2 * t[:, None]
    quaternion = np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (frames, envs, 1))
    rec = Recording(t, {"position_ned": position, "quaternion": quaternion, "euler": euler})
    names = [f"Wing {e}, lead" if e == 0 else f"Wing {e}" for e in range(envs)]
    path = write_acmi(rec, tmp_path / "formation.acmi", names=names, reference_time=WHEN)
    text = path.read_text(encoding="utf-8")
    assert "Name=Wing 0\\, lead" in text
    parsed = read_acmi(path)
    assert sorted(parsed.objects) == [format(0x101 + e, "x") for e in range(envs)]
    assert [parsed.objects[format(0x101 + e, "x")].properties["Name"] for e in range(envs)] == names
    assert len({t.properties["Color"] for t in parsed.objects.values()}) == envs
    _check_track(rec, parsed, ReferencePoint())


def test_parser_omitted_components_and_other_forms() -> None:
    text = "\n".join([
        "\ufeffFileType=text/acmi/tacview", "FileVersion=2.2",
        "0,ReferenceLongitude=10", "0,ReferenceLatitude=20", "0,Comments=two\\", "lines",
        "#0", "a1,T=0.5|0.25|100|1|2|3,Name=A\\,B,IAS=20",
        "b2,T=0.1|0.2|50",
        "#1.5", "a1,T=|||4|5|6", "b2,T=0.3|0.4|60|7|8|9|1000|2000|45",
        "#2", "a1,T=0.75||,IAS=21", "-b2",
        "#3",
    ])
    parsed = parse_acmi(text)
    assert parsed.header["Comments"] == "two\nlines"
    np.testing.assert_array_equal(parsed.frames, [0.0, 1.5, 2.0, 3.0])
    a = parsed.objects["a1"]
    assert a.properties["Name"] == "A,B"
    np.testing.assert_array_equal(a.longitude, [10.5, 10.5, 10.75, 10.75])
    np.testing.assert_array_equal(a.latitude, [20.25] * 4)
    np.testing.assert_array_equal(a.altitude, [100.0] * 4)
    np.testing.assert_array_equal(a.roll, [1.0, 4.0, 4.0, 4.0])
    np.testing.assert_array_equal(a.yaw, [3.0, 6.0, 6.0, 6.0])
    np.testing.assert_array_equal(a.values["IAS"], [20.0, 20.0, 21.0, 21.0])
    b = parsed.objects["b2"]
    np.testing.assert_array_equal(b.time, [0.0, 1.5])  # removed at t = 2
    assert np.isnan(b.roll[0]) and b.roll[1] == 7.0 and b.altitude[1] == 60.0
    with pytest.raises(ValueError, match="not an ACMI file"):
        parse_acmi("hello\nworld\n")
    with pytest.raises(ValueError, match="components"):
        parse_acmi("FileType=text/acmi/tacview\nFileVersion=2.2\n#0\n1,T=1|2\n")


def test_acmi_bad_inputs(recording: Recording, tmp_path) -> None:
    with pytest.raises(ValueError, match=r"\.acmi"):
        write_acmi(recording, tmp_path / "flight.csv")
    with pytest.raises(ValueError, match="one entry per aircraft"):
        write_acmi(recording, tmp_path / "flight.acmi", names=["only one"])
    with pytest.raises(ValueError, match="no such file"):
        read_acmi(tmp_path / "missing.acmi")


# ---------------------------------------------------------------------------------------- real-time
def _read_until(sock: socket.socket, marker: bytes, data: bytes = b"") -> bytes:
    deadline = time.monotonic() + 5.0
    while marker not in data and time.monotonic() < deadline:
        chunk = sock.recv(65536)
        if not chunk:
            break
        data += chunk
    return data


def test_tacview_server_without_client_does_not_block() -> None:
    with TacviewServer(port=0, num_envs=2) as server:
        assert server.host == "127.0.0.1"
        start = time.perf_counter()
        for k in range(50):
            assert server.send_frame(0.02 * k, np.zeros((2, 3)), np.zeros((2, 3))) == 0
        assert time.perf_counter() - start < 1.0


def test_tacview_server_handshake_and_frames(recording: Recording) -> None:
    ref = ReferencePoint(47.4647, 8.5492, 432.0)
    with TacviewServer(port=0, num_envs=2, reference=ref, names=["one", "two, too"],
                       reference_time=WHEN) as server, \
            socket.create_connection((server.host, server.port), timeout=5.0) as client:
        server.poll()
        greeting = _read_until(client, b"\0")
        assert greeting == b"XtraLib.Stream.0\nTacview.RealTimeTelemetry.0\nfalcon-rl\n\0"
        client.sendall(client_handshake("pytest"))
        for _ in range(100):
            server.poll()
            if server.num_clients:
                break
            time.sleep(0.01)
        assert server.num_clients == 1
        for k in range(recording.num_frames):
            assert server.send_frame(float(recording.time[k]), recording["position_ned"][k],
                                     recording["euler"][k]) == 1
        last = f"#{recording.time[-1]:.6f}".rstrip("0").rstrip(".").encode()
        data = _read_until(client, last + b"\n")
    parsed = parse_acmi(data.decode("utf-8"))
    assert parsed.header["ReferenceTime"] == "2024-05-17T09:30:00Z"
    assert parsed.objects["102"].properties["Name"] == "two, too"
    _check_track(recording, parsed, ref)


def test_tacview_server_rejects_bad_handshakes() -> None:
    with TacviewServer(port=0, password="secret") as server:
        for handshake in (b"Nonsense\n\0", client_handshake("pytest", "wrong"), client_handshake("pytest")):
            with socket.create_connection((server.host, server.port), timeout=5.0) as client:
                server.poll()
                _read_until(client, b"\0")
                client.sendall(handshake)
                for _ in range(20):
                    server.poll()
                    time.sleep(0.005)
                assert server.num_clients == 0
        with socket.create_connection((server.host, server.port), timeout=5.0) as client:
            server.poll()
            _read_until(client, b"\0")
            client.sendall(client_handshake("pytest", "secret"))
            for _ in range(100):
                server.poll()
                if server.num_clients:
                    break
                time.sleep(0.01)
            assert server.num_clients == 1
    assert password_hashes("") >= {"0"}


def test_tacview_server_bad_inputs() -> None:
    with pytest.raises(ValueError, match="port"):
        TacviewServer(port=70000)
    with pytest.raises(ValueError, match="port"):
        TacviewServer(port=-1)
    with TacviewServer(port=0, num_envs=2) as server:
        with pytest.raises(ValueError, match=r"\[2, 3\]"):
            server.send_frame(0.0, np.zeros((3, 3)), np.zeros((3, 3)))
        with pytest.raises(ValueError, match="finite"):
            server.send_frame(0.0, np.full((2, 3), np.nan), np.zeros((2, 3)))
