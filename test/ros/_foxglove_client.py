"""A minimal Foxglove WebSocket protocol client for the tests (stdlib only, not a test module).

Speaks just enough RFC 6455 (client handshake, masked text frames out, unfragmented
or fragmented frames in, ping answered) and of the Foxglove protocol (``serverInfo``,
``advertise``, ``subscribe``, binary ``messageData``) to check what the bridge serves.
"""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import time
from typing import Any

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
MESSAGE_DATA = 0x01  # binary opcode of a server messageData frame


class FoxgloveClient:
    """One connection to ``ws://host:port``; :meth:`receive` returns the next JSON or binary message."""

    def __init__(self, host: str, port: int, timeout: float = 30.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout)
        key = base64.b64encode(os.urandom(16)).decode()
        request = (f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                   f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                   f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {', '.join(SUBPROTOCOLS)}\r\n\r\n")
        self.sock.sendall(request.encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                raise ConnectionError(f"handshake: connection closed after {head!r}")
            head += chunk
        status = head.split(b"\r\n", 1)[0]
        if b" 101 " not in status + b" ":
            raise ConnectionError(f"handshake refused: {head.decode(errors='replace')}")
        self.subprotocol = next((line.split(b":", 1)[1].strip().decode() for line in head.split(b"\r\n")
                                 if line.lower().startswith(b"sec-websocket-protocol:")), "")

    def _read(self, n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("connection closed by the server")
            buf += chunk
        return buf

    def _send_frame(self, opcode: int, payload: bytes) -> None:
        mask = os.urandom(4)
        n = len(payload)
        head = bytes([0x80 | opcode])
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 1 << 16:
            head += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            head += bytes([0x80 | 127]) + struct.pack(">Q", n)
        self.sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    def send_json(self, obj: dict[str, Any]) -> None:
        self._send_frame(0x1, json.dumps(obj).encode())

    def receive(self) -> dict[str, Any] | bytes:
        """The next data message: a dict (text frame, JSON) or bytes (binary frame)."""
        data, first_op = b"", None
        while True:
            b0, b1 = self._read(2)
            op, n = b0 & 0x0F, b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._read(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._read(8))[0]
            mask = self._read(4) if b1 & 0x80 else None
            payload = self._read(n)
            if mask:
                payload = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
            if op == 0x8:
                raise ConnectionError(f"server closed the connection: {payload!r}")
            if op == 0x9:
                self._send_frame(0xA, payload)
                continue
            if op == 0xA:
                continue
            first_op = op if first_op is None else first_op
            data += payload
            if b0 & 0x80:
                return json.loads(data) if first_op == 0x1 else data

    def wait_for(self, predicate: Any, timeout: float, what: str) -> dict[str, Any] | bytes:
        """Receive until a message satisfies ``predicate``; AssertionError after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.sock.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                msg = self.receive()
            except TimeoutError:
                break
            if predicate(msg):
                return msg
        raise AssertionError(f"timed out after {timeout} s waiting for {what}")

    def close(self) -> None:
        try:
            self._send_frame(0x8, struct.pack(">H", 1000))
        except OSError:
            pass
        self.sock.close()


def parse_message_data(frame: bytes) -> tuple[int, int, bytes]:
    """``(subscription id, log time ns, payload)`` of a binary messageData frame."""
    if not frame or frame[0] != MESSAGE_DATA:
        raise ValueError(f"`frame`: expected opcode 0x01 (messageData), got {frame[:1]!r}")
    sub, stamp = struct.unpack_from("<IQ", frame, 1)
    return sub, stamp, frame[13:]
