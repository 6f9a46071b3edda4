"""The FlightGear native-fdm (FGNetFDM v24) encoder, decoder and UDP streamer."""

from __future__ import annotations

import os
import shutil
import socket
import struct
import subprocess
import time

import numpy as np
import pytest
import torch

import falcon_rl
from falcon_rl.bridges.flightgear import (
    FDM_FIELDS,
    FDM_SIZE,
    FlightGearStreamer,
    decode_fdm,
    encode_fdm,
    fdm_values,
)
from falcon_rl.recording import Recording, record_simulator
from falcon_rl.viz.geodesy import ReferencePoint, euler_from_local_level, geodetic_to_ned


@pytest.fixture(scope="module")
def sim_and_recording() -> tuple[falcon_rl.Simulator, Recording]:
    sim = falcon_rl.Simulator(falcon_rl.load_airframe("volantex_ranger"), num_envs=2, backend="torch")
    sim.reset()
    commands = torch.tensor([[0.1, 0.4, 0.0, 0.7], [-0.1, -0.3, 0.2, 0.5]])
    return sim, record_simulator(sim, commands, steps=40, substeps=2)


@pytest.fixture
def receiver():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    yield sock
    sock.close()


def _drain(sock: socket.socket) -> list[dict]:
    packets = []
    sock.settimeout(0.2)
    try:
        while True:
            data = sock.recv(4096)
            assert len(data) == FDM_SIZE
            packets.append(decode_fdm(data))
    except TimeoutError:
        pass
    return packets


def test_packet_is_408_bytes_big_endian_version_24() -> None:
    packet = encode_fdm({})
    assert len(packet) == FDM_SIZE == 408
    assert struct.unpack(">I", packet[:4])[0] == 24
    packet = encode_fdm({"longitude": 1.25, "spoilers": 0.5, "warp": -3})
    assert struct.unpack(">d", packet[8:16])[0] == 1.25  # after version and padding
    assert struct.unpack(">f", packet[-4:])[0] == 0.5  # spoilers is the last field
    assert struct.unpack(">i", packet[-48:-44])[0] == -3  # warp, before visibility and 10 surfaces
    assert len(FDM_FIELDS) == 58


def test_encode_decode_round_trip() -> None:
    rng = np.random.default_rng(0)
    values: dict = {}
    for name, code in FDM_FIELDS:
        count = int(code[:-1] or 1)
        if code[-1] in "Ii":
            sample = rng.integers(0, 1000, count).tolist()
        else:
            sample = rng.normal(size=count).tolist()
        values[name] = sample if len(code) > 1 else sample[0]
    decoded = decode_fdm(encode_fdm(values))
    assert decoded.keys() == values.keys()
    for name, code in FDM_FIELDS:
        if code[-1] == "d" or code[-1] in "Ii":
            assert decoded[name] == values[name], name
        else:
            np.testing.assert_array_equal(np.float32(decoded[name]), np.float32(values[name]))


def test_stream_reproduces_the_recording(sim_and_recording, receiver) -> None:
    _, rec = sim_and_recording
    ref = ReferencePoint(47.4647, 8.5492, 432.0)
    with FlightGearStreamer(port=receiver.getsockname()[1], reference=ref) as streamer:
        assert streamer.stream(rec, speed=0, env=1) == rec.num_frames
    packets = _drain(receiver)
    assert len(packets) == rec.num_frames
    lat = np.degrees([p["latitude"] for p in packets])
    lon = np.degrees([p["longitude"] for p in packets])
    alt = np.array([p["altitude"] for p in packets])
    ned = geodetic_to_ned(ref, lat, lon, alt)
    assert np.abs(ned - rec["position_ned"][:, 1]).max() < 1e-6  # doubles on the wire
    local = np.array([[p["phi"], p["theta"], p["psi"]] for p in packets], dtype=np.float64)
    euler = euler_from_local_level(ref, ned, local)
    error = (euler - rec["euler"][:, 1] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(error).max() < 1e-6  # float32 angles
    assert all(p["version"] == 24 for p in packets)
    np.testing.assert_allclose([p["agl"] for p in packets], rec["height"][:, 1], rtol=1e-6)
    np.testing.assert_allclose([p["alpha"] for p in packets], rec["alpha"][:, 1], atol=1e-7)
    np.testing.assert_allclose([p["v_north"] * 0.3048 for p in packets], rec["velocity_ned"][:, 1, 0],
                               rtol=1e-5)
    surfaces = rec["surface_position"][:, 1]
    elevator = np.array([p["elevator"] for p in packets])
    np.testing.assert_allclose(elevator, np.clip(surfaces[:, 0] / 0.349066, -1, 1), atol=1e-5)
    aileron = np.array([p["left_aileron"] for p in packets])
    np.testing.assert_allclose(aileron, surfaces[:, 1] / 0.261799, atol=1e-5)
    np.testing.assert_allclose([p["right_aileron"] for p in packets], -aileron)
    assert packets[0]["num_engines"] == rec["throttle"].shape[2]


def test_stream_is_paced(sim_and_recording, receiver) -> None:
    _, rec = sim_and_recording
    span = float(rec.time[-1] - rec.time[0])
    speed = span / 0.3  # the whole recording in 0.3 s
    with FlightGearStreamer(port=receiver.getsockname()[1], rate_hz=50.0) as streamer:
        start = time.perf_counter()
        sent = streamer.stream(rec, speed=speed)
        elapsed = time.perf_counter() - start
    assert 0.28 <= elapsed < 1.5
    assert 10 <= sent <= 0.3 * 50 + 2  # frames skipped to respect rate_hz
    assert len(_drain(receiver)) == sent


def test_send_a_simulator_state(sim_and_recording, receiver) -> None:
    sim, _ = sim_and_recording
    state = sim.state
    with FlightGearStreamer(port=receiver.getsockname()[1], rate_hz=1000.0) as streamer:
        packet = streamer.send(state, env=1)
        streamer.send({k: v[0] for k, v in state.items() if k in ("position_ned", "quaternion")})
    first, second = _drain(receiver)
    assert decode_fdm(packet) == first
    ned = geodetic_to_ned(None, np.degrees(first["latitude"]), np.degrees(first["longitude"]),
                          first["altitude"])
    np.testing.assert_allclose(ned, state["position_ned"][1].numpy(), atol=1e-6)
    assert second["altitude"] == pytest.approx(4.0 - float(state["position_ned"][0, 2]), abs=1e-3)


def test_surfaces_at_their_limits() -> None:
    limits = {"elevator": (-0.3, 0.2), "aileron": (-0.25, 0.25), "rudder": (-0.25, 0.25)}
    values = fdm_values({"position_ned": [0, 0, -10], "euler": [0, 0, 0],
                         "surface_position": [-0.3, 0.5, 0.1]}, surface_limits=limits)
    assert values["elevator"] == -1.0 and values["left_aileron"] == 1.0 and values["right_aileron"] == -1.0
    assert values["rudder"] == pytest.approx(0.4)


def test_flightgear_bad_inputs() -> None:
    for port in (0, 70000, "5550"):
        with pytest.raises(ValueError, match="port"):
            FlightGearStreamer(port=port)
    with pytest.raises(ValueError, match="rate_hz"):
        FlightGearStreamer(rate_hz=0)
    with pytest.raises(ValueError, match="408"):
        decode_fdm(b"\0" * 407)
    with pytest.raises(ValueError, match="unknown"):
        encode_fdm({"airspeed": 1.0})
    with pytest.raises(ValueError, match="finite"):
        encode_fdm({"phi": float("nan")})
    with pytest.raises(ValueError, match="holds 4"):
        encode_fdm({"rpm": [1, 2, 3, 4, 5]})
    with pytest.raises(ValueError, match="position_ned"):
        fdm_values({"euler": [0, 0, 0]})
    with pytest.raises(ValueError, match="non-finite"):
        fdm_values({"position_ned": [0, np.inf, 0], "euler": [0, 0, 0]})
    with FlightGearStreamer() as streamer, pytest.raises(ValueError, match="speed"):
        streamer.stream(Recording(np.zeros(1), {"position_ned": np.zeros((1, 1, 3)),
                                                "quaternion": np.ones((1, 1, 4))}), speed=-1)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("fgfs") is None, reason="FlightGear (fgfs) is not installed")
@pytest.mark.skipif(not os.environ.get("DISPLAY"), reason="FlightGear needs a display")
def test_flightgear_accepts_the_stream(sim_and_recording) -> None:
    """Launch FlightGear with the null FDM and its property server, stream, and read the position back.
    FlightGear has no true headless mode; it runs with the launcher, sound and splash screen off."""
    _, rec = sim_and_recording
    fdm_port, props_port = 5551, 5552
    process = subprocess.Popen(
        ["fgfs", "--fdm=null", f"--native-fdm=socket,in,60,,{fdm_port},udp", f"--props={props_port}",
         "--airport=KSFO", "--disable-sound", "--disable-splash-screen", "--disable-ai-traffic",
         "--disable-real-weather-fetch", "--geometry=320x240"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 240.0
        with FlightGearStreamer(port=fdm_port) as streamer:
            latitude = None
            while time.monotonic() < deadline and latitude is None:
                streamer.stream(rec.select([0]), speed=0)
                try:
                    with socket.create_connection(("127.0.0.1", props_port), timeout=2.0) as telnet:
                        telnet.sendall(b"get /position/latitude-deg\r\n")
                        reply = telnet.recv(4096).decode(errors="replace")
                    latitude = float(reply.split("'")[1])
                except (OSError, IndexError, ValueError):
                    time.sleep(2.0)
        assert latitude is not None
        assert latitude == pytest.approx(ReferencePoint().latitude_deg, abs=0.01)
    finally:
        process.terminate()
        process.wait(timeout=30)
