"""A thread on the master side of a pty that answers Dynamixel Protocol 2.0 like a chain of X-series motors.

It is written from the protocol description (header, byte stuffing, CRC-16 with polynomial
0x8005), independently of dynamixel-sdk, so the driver is tested against the wire format.
"""

from __future__ import annotations

import os
import select
import threading
import tty

HEADER = bytes([0xFF, 0xFF, 0xFD, 0x00])
PING, READ, WRITE, SYNC_READ, SYNC_WRITE, STATUS = 0x01, 0x02, 0x03, 0x82, 0x83, 0x55


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


CRC_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    crc = 0
    for byte in data:
        crc = ((crc << 8) ^ CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert 0xFD after every FF FF FD inside instruction/params (Protocol 2.0 byte stuffing)."""
    out = bytearray()
    for b in body:
        out.append(b)
        if len(out) >= 3 and out[-3:] == b"\xff\xff\xfd":
            out.append(0xFD)
    return bytes(out)


def packet(dxl_id: int, instruction: int, params: bytes) -> bytes:
    body = stuff(bytes([instruction]) + params)
    length = len(body) + 2
    head = HEADER + bytes([dxl_id, length & 0xFF, length >> 8]) + body
    crc = crc16(head)
    return head + bytes([crc & 0xFF, crc >> 8])


class FakeDynamixelChain:
    """Motors with the given ids; `positions[id]` is the Present Position register (int32)."""

    def __init__(self, ids: list[int], positions: dict[int, int] | None = None) -> None:
        self.ids = list(ids)
        self.positions = dict(positions or {i: 2048 for i in ids})
        self.registers: dict[tuple[int, int], bytes] = {}  # (id, address) -> bytes written
        self.answering = True
        self.bad_crc_packets = 0
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        self.device = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def __enter__(self) -> FakeDynamixelChain:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        os.close(self.master)
        os.close(self.slave)

    def _loop(self) -> None:
        buf = bytearray()
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.01)
            if not ready:
                continue
            try:
                buf += os.read(self.master, 4096)
            except OSError:
                continue
            while True:
                start = buf.find(HEADER)
                if start < 0 or len(buf) < start + 7:
                    break
                length = buf[start + 5] | (buf[start + 6] << 8)
                end = start + 7 + length
                if len(buf) < end:
                    break
                pkt = bytes(buf[start:end])
                del buf[:end]
                self._handle(pkt)

    def _reply(self, dxl_id: int, params: bytes) -> None:
        if not self.answering:  # a broken return line: commands still arrive, no status comes back
            return
        os.write(self.master, packet(dxl_id, STATUS, bytes([0]) + params))

    def _handle(self, pkt: bytes) -> None:
        if crc16(pkt[:-2]) != (pkt[-2] | (pkt[-1] << 8)):
            self.bad_crc_packets += 1
            return
        dxl_id, instruction = pkt[4], pkt[7]
        params = pkt[8:-2].replace(b"\xff\xff\xfd\xfd", b"\xff\xff\xfd")
        if instruction == PING and dxl_id in self.ids:
            self._reply(dxl_id, bytes([0x06, 0x04, 0x2E]))  # XM430-W350 model 1030, firmware 46
        elif instruction == SYNC_READ:
            address = params[0] | (params[1] << 8)
            size = params[2] | (params[3] << 8)
            for target in params[4:]:
                if target in self.ids and address == 132 and size == 4:
                    self._reply(target, (self.positions[target] & 0xFFFFFFFF).to_bytes(4, "little"))
        elif instruction == WRITE and dxl_id in self.ids:
            address = params[0] | (params[1] << 8)
            self.registers[(dxl_id, address)] = params[2:]
            self._reply(dxl_id, b"")
        elif instruction == SYNC_WRITE:
            address = params[0] | (params[1] << 8)
            size = params[2] | (params[3] << 8)
            data = params[4:]
            for k in range(0, len(data), size + 1):
                self.registers[(data[k], address)] = data[k + 1 : k + 1 + size]
