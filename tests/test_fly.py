"""``falcon-rl fly`` and ``falcon-rl replay``: a flown circle written as a recording, a Tacview file that
follows the track, an animated GIF of the banked glyph, the panels and a FlightGear stream decoded
from a loopback socket; bad options exit 2 before anything flies."""

from __future__ import annotations

import contextlib
import io
import json
import socket
import threading

import imageio.v3 as iio
import numpy as np
import pytest

from falcon_rl.bridges.flightgear import decode_fdm
from falcon_rl.cli import main
from falcon_rl.recording import Recording
from falcon_rl.viz.acmi import read_acmi
from falcon_rl.viz.geodesy import DEFAULT_REFERENCE, geodetic_to_ned


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """An LQR circle on the Volantex Ranger, 6 s, with every file output: (folder, JSON document)."""
    out = tmp_path_factory.mktemp("fly")
    args = ["fly", "--controller", "lqr", "--task", "attitude", "--airframe", "volantex_ranger",
            "--maneuver", "circle", "--seconds", "6", "--acmi", str(out / "a.acmi"), "--gif",
            str(out / "a.gif"), "--plots", str(out / "p"), "--record", str(out / "r.npz"), "--json"]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(args) == 0
    return out, json.loads(printed.getvalue())


def test_fly_writes_every_output(flown):
    out, doc = flown
    assert doc["terminated"] == 0 and doc["seconds"] == pytest.approx(6.0)
    rec = Recording.load(out / "r.npz")
    assert rec.meta["controller"] == "lqr" and rec.meta["maneuver"] == "circle"
    # The circle banks to about 28 deg after the 2 s lead-in and the 2 s roll-in.
    bank = np.degrees(rec["euler"][:, 0, 0])
    assert bank[: int(1.5 / rec.dt)].max() < 2.0 and 20.0 < bank[-1] < 35.0
    # ACMI: header, reference point, monotonic frames, and a track that follows the flight.
    acmi = read_acmi(out / "a.acmi")
    assert acmi.header["FileType"] == "text/acmi/tacview" and acmi.header["FileVersion"] == "2.2"
    assert "ReferenceLongitude" in acmi.header and "ReferenceTime" in acmi.header
    assert np.all(np.diff(acmi.frames) > 0)
    (track,) = acmi.objects.values()
    ned = geodetic_to_ned(DEFAULT_REFERENCE, track.latitude, track.longitude, track.altitude)
    recorded = rec["position_ned"][:, 0]
    index = np.searchsorted(rec.time, track.time)
    np.testing.assert_allclose(ned, recorded[index], atol=0.05)
    np.testing.assert_allclose(track.roll[-1], bank[-1], atol=0.05)
    # GIF: the glyph banks, so late frames differ from the level ones.
    frames = iio.imread(out / "a.gif", index=None)
    assert frames.ndim == 4 and frames.shape[0] > 10 and frames.shape[-1] == 3
    assert (frames[-1] != frames[0]).mean() > 0.01
    assert {p.name for p in (out / "p").iterdir()} >= {"states.png", "forces.png", "actuators.png",
                                                      "ground_effect.png", "tracking.png"}


def test_replay_streams_to_flightgear(flown, capsys):
    out, _ = flown
    datagrams: list[bytes] = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as receiver:
        receiver.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        receiver.bind(("127.0.0.1", 0))
        receiver.settimeout(2.0)
        port = receiver.getsockname()[1]

        def receive() -> None:  # drain while the replay sends, so that no datagram is dropped
            with contextlib.suppress(TimeoutError):
                while True:
                    datagrams.append(receiver.recv(1024))

        thread = threading.Thread(target=receive)
        thread.start()
        code = main(["replay", str(out / "r.npz"), "--flightgear", f"127.0.0.1:{port}",
                     "--flightgear-speed", "0", "--json"])
        thread.join()
    assert code == 0
    packets = [decode_fdm(datagram) for datagram in datagrams]
    sent = json.loads(capsys.readouterr().out)["outputs"]["flightgear_packets"]
    rec = Recording.load(out / "r.npz")
    assert sent == rec.num_frames and len(packets) == sent
    last = packets[-1]
    ned = geodetic_to_ned(DEFAULT_REFERENCE, np.degrees(last["latitude"]), np.degrees(last["longitude"]),
                          last["altitude"])
    np.testing.assert_allclose(ned, rec["position_ned"][-1, 0], atol=0.05)
    np.testing.assert_allclose(last["phi"], rec["euler"][-1, 0, 0], atol=2e-3)
    np.testing.assert_allclose(last["theta"], rec["euler"][-1, 0, 1], atol=2e-3)


@pytest.mark.parametrize(("extra", "message"), [
    (["--gif", "x.png"], "x.png' must end in .gif"),
    (["--acmi", "x.txt"], "must end in .acmi"),
    (["--flightgear", "localhost"], "must be HOST:PORT"),
    (["--flightgear", "localhost:70000"], "must be HOST:PORT"),
    (["--task", "altitude", "--maneuver", "circle"], "--maneuver does not apply"),
    (["--controller", "mppi", "--task", "path_following"], "--controller"),
])
def test_fly_refuses_bad_options(extra, message, capsys, tmp_path):
    args = ["fly", "--controller", "lqr", "--task", "attitude", "--seconds", "1", *extra]
    args = [a.replace("x.", str(tmp_path / "x.")) for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_replay_refuses_what_is_not_a_recording(tmp_path, capsys):
    bogus = tmp_path / "bogus.npz"
    bogus.write_text("hello")
    assert main(["replay", str(bogus)]) == 2
    assert "not a recording" in capsys.readouterr().err
