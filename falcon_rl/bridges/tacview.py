"""Tacview real-time telemetry: stream the aircraft to Tacview while the simulation runs.

Tacview's real-time protocol (public "Real-time Telemetry" reference; watching it needs Tacview
Advanced) is ACMI 2.2 text over TCP. The application is the host: it listens (Tacview's default port
is 42674) and Tacview connects as a client. What this module implements:

1. host -> client: ``XtraLib.Stream.0\\n`` ``Tacview.RealTimeTelemetry.0\\n`` ``<host name>\\n`` ``\\0``;
2. client -> host: ``XtraLib.Stream.0\\n`` ``Tacview.RealTimeTelemetry.0\\n`` ``<client name>\\n``
   ``<password hash>\\0``. The hash of an empty password is ``0``; otherwise it is a CRC of the
   password's UTF-16LE bytes in lowercase hex. Clients have used CRC-32 (ISO-HDLC) and CRC-64 (ECMA,
   "WE" variant); when a password is set, the host accepts either. A client whose first two lines
   differ, or whose hash does not match, is disconnected;
3. host -> client: the ACMI header (``FileType``, ``FileVersion``, ``ReferenceTime``, reference
   longitude and latitude) and then, at each :meth:`TacviewServer.send_frame`, a ``#<t>`` line and one
   line per aircraft (full ``T=`` and Name/Type/Color on a client's first frame, changes only later).

Not checked against a running Tacview (the handshake follows the public reference and other open
exporters). The server binds to 127.0.0.1 unless told otherwise; :meth:`send_frame` never blocks
waiting for a client (it polls for connections and handshakes without blocking; a client that cannot
take a frame within ``send_timeout`` seconds is dropped).

Connections cannot pile up: one that has not completed its handshake ``handshake_timeout`` seconds
(:data:`DEFAULT_HANDSHAKE_TIMEOUT`, 5 s) after it was accepted is closed, and at most ``max_clients``
connections (:data:`DEFAULT_MAX_CLIENTS`, 8; handshaking ones included) are held: a connection beyond
that is closed as soon as it is accepted. Both are enforced when :meth:`poll` runs (every
:meth:`send_frame` calls it), so an idle or silent peer delays a real client by at most
``handshake_timeout``.
"""

from __future__ import annotations

import socket
import time
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np

from ..viz.acmi import ACMI_COLORS, FIRST_OBJECT_ID, AcmiObjectEncoder, acmi_header, format_number
from ..viz.geodesy import DEFAULT_REFERENCE, ReferencePoint, euler_to_local_level, ned_to_geodetic

#: Tacview's default real-time telemetry port.
DEFAULT_PORT = 42674
#: The first two lines of either side's handshake.
HANDSHAKE_LINES = ("XtraLib.Stream.0", "Tacview.RealTimeTelemetry.0")
#: Seconds a connection may take to complete its handshake before it is closed.
DEFAULT_HANDSHAKE_TIMEOUT = 5.0
#: Most connections held at once (handshaking or receiving frames); more are closed when accepted.
DEFAULT_MAX_CLIENTS = 8
_MAX_HANDSHAKE = 4096
#: Most connections one :meth:`TacviewServer.poll` accepts (the rest wait for the next poll).
_MAX_ACCEPTS_PER_POLL = 64
#: Connections the kernel queues between two polls.
_LISTEN_BACKLOG = 64


def _crc64_we(data: bytes) -> int:
    crc = 0xFFFFFFFFFFFFFFFF
    for byte in data:
        crc ^= byte << 56
        for _ in range(8):
            crc = ((crc << 1) ^ 0x42F0E1EBA9EA3693) if crc & (1 << 63) else crc << 1
            crc &= 0xFFFFFFFFFFFFFFFF
    return crc ^ 0xFFFFFFFFFFFFFFFF


def password_hashes(password: str) -> set[str]:
    """The hashes a client may send for ``password``: ``{"0"}`` when empty, else the CRC-32 and CRC-64
    of its UTF-16LE bytes in lowercase hex."""
    if not password:
        return {"0", ""}
    data = password.encode("utf-16-le")
    return {format(zlib.crc32(data) & 0xFFFFFFFF, "x"), format(_crc64_we(data), "x")}


def host_handshake(host_name: str) -> bytes:
    """The host's handshake bytes."""
    return f"{HANDSHAKE_LINES[0]}\n{HANDSHAKE_LINES[1]}\n{host_name}\n\0".encode()


def client_handshake(client_name: str, password: str = "") -> bytes:
    """A client's handshake bytes (CRC-64 hash; ``0`` for no password), as Tacview sends it."""
    digest = format(_crc64_we(password.encode("utf-16-le")), "x") if password else "0"
    return f"{HANDSHAKE_LINES[0]}\n{HANDSHAKE_LINES[1]}\n{client_name}\n{digest}\0".encode()


@dataclass
class _Client:
    sock: socket.socket
    address: tuple
    deadline: float
    received: bytes = b""
    ready: bool = False
    name: str = ""
    encoders: list[AcmiObjectEncoder] = field(default_factory=list)


class TacviewServer:
    """A real-time telemetry host for ``num_envs`` aircraft; Tacview connects to ``host:port``.

    ``port=0`` picks a free port (read :attr:`port`). ``names``/``colors`` [E] label the aircraft.
    ``handshake_timeout`` (s) and ``max_clients`` bound the connections held (see the module
    docstring). Use as a context manager or call :meth:`close`."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *, num_envs: int = 1,
                 reference: ReferencePoint | None = None, names: Sequence[str] | None = None,
                 colors: Sequence[str] | None = None, host_name: str = "falcon-rl", password: str = "",
                 reference_time: datetime | None = None, send_timeout: float = 1.0,
                 handshake_timeout: float = DEFAULT_HANDSHAKE_TIMEOUT,
                 max_clients: int = DEFAULT_MAX_CLIENTS) -> None:
        if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise ValueError(f"port must be an int in [0, 65535], got {port!r}")
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive int, got {num_envs!r}")
        if "\n" in host_name or "\0" in host_name:
            raise ValueError("host_name must not contain line breaks or NUL")
        if not send_timeout > 0:
            raise ValueError(f"send_timeout must be > 0 s, got {send_timeout}")
        if not 0 < handshake_timeout < float("inf"):
            raise ValueError(f"handshake_timeout must be a finite number of seconds > 0, "
                             f"got {handshake_timeout}")
        if not isinstance(max_clients, int) or isinstance(max_clients, bool) or max_clients < 1:
            raise ValueError(f"max_clients must be a positive int, got {max_clients!r}")
        self.num_envs = num_envs
        self.reference = reference or DEFAULT_REFERENCE
        self.names = ([str(n) for n in names] if names is not None
                      else [f"aircraft {e}" for e in range(num_envs)])
        self.colors = ([str(c) for c in colors] if colors is not None
                       else [ACMI_COLORS[e % len(ACMI_COLORS)] for e in range(num_envs)])
        if len(self.names) != num_envs or len(self.colors) != num_envs:
            raise ValueError(f"names and colors must have {num_envs} entries")
        self.host_name = host_name
        self.reference_time = reference_time
        self.send_timeout = float(send_timeout)
        self.handshake_timeout = float(handshake_timeout)
        self.max_clients = max_clients
        self._hashes = password_hashes(password)
        self._clients: list[_Client] = []
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._listener.bind((host, port))
        except OSError as error:
            self._listener.close()
            raise ValueError(f"cannot listen on {host}:{port} ({error.strerror or error})") from None
        self._listener.listen(_LISTEN_BACKLOG)
        self._listener.setblocking(False)
        self.host, self.port = self._listener.getsockname()[:2]

    # ------------------------------------------------------------------------------ connections
    @property
    def num_clients(self) -> int:
        """Clients past the handshake (receiving frames)."""
        return sum(c.ready for c in self._clients)

    @property
    def num_connections(self) -> int:
        """Connections held: clients past the handshake and those still handshaking."""
        return len(self._clients)

    def poll(self) -> None:
        """Accept pending connections (closing those beyond ``max_clients``), close handshakes older
        than ``handshake_timeout`` and advance the others; never blocks."""
        for _ in range(_MAX_ACCEPTS_PER_POLL):
            try:
                sock, address = self._listener.accept()
            except OSError:  # none pending, or out of file descriptors: the handshakes still advance
                break
            self._admit(sock, address)
        now = time.monotonic()
        for client in [c for c in self._clients if not c.ready]:
            if now > client.deadline:
                self._drop(client)
            else:
                self._advance_handshake(client)

    def _admit(self, sock: socket.socket, address: tuple) -> None:
        """Greet a new connection, or close it at once when ``max_clients`` are held."""
        if len(self._clients) >= self.max_clients:
            sock.close()
            return
        sock.setblocking(False)
        try:
            sock.sendall(host_handshake(self.host_name))
        except OSError:
            sock.close()
            return
        self._clients.append(_Client(sock, address, time.monotonic() + self.handshake_timeout))

    def _advance_handshake(self, client: _Client) -> None:
        try:
            while b"\0" not in client.received and len(client.received) <= _MAX_HANDSHAKE:
                chunk = client.sock.recv(1024)
                if not chunk:
                    return self._drop(client)
                client.received += chunk
        except (BlockingIOError, InterruptedError):
            pass
        except OSError:
            return self._drop(client)
        if b"\0" not in client.received:
            if len(client.received) > _MAX_HANDSHAKE:
                self._drop(client)
            return None
        text = client.received.split(b"\0", 1)[0].decode("utf-8", errors="replace")
        lines = text.split("\n")
        if tuple(lines[:2]) != HANDSHAKE_LINES or len(lines) < 3:
            return self._drop(client)
        digest = lines[3].strip().lower() if len(lines) > 3 else ""
        if digest not in self._hashes:
            return self._drop(client)
        client.name = lines[2]
        header = acmi_header(self.reference, self.reference_time, title="falcon-rl real-time telemetry")
        if not self._write(client, "\n".join(header) + "\n"):
            return None
        client.ready = True
        client.encoders = [AcmiObjectEncoder(FIRST_OBJECT_ID + e, self.names[e], self.colors[e])
                           for e in range(self.num_envs)]
        return None

    def _drop(self, client: _Client) -> None:
        try:
            client.sock.close()
        finally:
            if client in self._clients:
                self._clients.remove(client)

    def _write(self, client: _Client, text: str) -> bool:
        try:
            client.sock.settimeout(self.send_timeout)
            client.sock.sendall(text.encode("utf-8"))
            client.sock.setblocking(False)
            return True
        except OSError:
            self._drop(client)
            return False

    # ------------------------------------------------------------------------------ frames
    def send_frame(self, t: float, positions: np.ndarray, attitudes: np.ndarray) -> int:
        """Send one frame to every connected client; returns how many received it.

        ``t`` s after the reference time; ``positions`` [E, 3] m NED about the reference point;
        ``attitudes`` [E, 3] rad (roll, pitch, yaw, aerospace ZYX, about the reference NED axes)."""
        positions = np.asarray(positions, dtype=np.float64)
        attitudes = np.asarray(attitudes, dtype=np.float64)
        shape = (self.num_envs, 3)
        if positions.shape != shape or attitudes.shape != shape:
            raise ValueError(f"positions and attitudes must be {list(shape)}, got {positions.shape} and "
                             f"{attitudes.shape}")
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(attitudes)) and np.isfinite(t)):
            raise ValueError("t, positions and attitudes must be finite")
        self.poll()
        ready = [c for c in self._clients if c.ready]
        if not ready:
            return 0
        ref = self.reference
        lat, lon, alt = ned_to_geodetic(ref, positions)
        att = np.degrees(euler_to_local_level(ref, positions, attitudes))
        yaw = np.mod(att[:, 2], 360.0)
        att[:, 2] = np.where(yaw >= 360.0 - 5e-5, yaw - 360.0, yaw)
        sent = 0
        for client in ready:
            lines = ["#" + format_number(float(t), 6)]
            for e, encoder in enumerate(client.encoders):
                line = encoder.line(float(lon[e] - ref.longitude_deg), float(lat[e] - ref.latitude_deg),
                                    float(alt[e]), *(float(a) for a in att[e]))
                if line is not None:
                    lines.append(line)
            sent += self._write(client, "\n".join(lines) + "\n")
        return sent

    def close(self) -> None:
        """Close every client and the listening socket."""
        for client in list(self._clients):
            self._drop(client)
        self._listener.close()

    def __enter__(self) -> TacviewServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["DEFAULT_HANDSHAKE_TIMEOUT", "DEFAULT_MAX_CLIENTS", "DEFAULT_PORT", "HANDSHAKE_LINES",
           "TacviewServer", "client_handshake", "host_handshake", "password_hashes"]
