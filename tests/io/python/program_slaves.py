#!/usr/bin/python3
"""master_slaves.py's slaves with the program download of DSP 302 v3.2.1 §9, written with
python-can alone (nothing here uses our C++ code): the independent peers of the software update
tests over the UDP multicast bus (tests/tools/program_udp_test.cpp).

Usage: program_slaves.py [--refuse-clear] [--flash-busy N] GROUP PORT TIMEOUT_S NODE...

Besides master_slaves.py's objects, every NODE has:
  - 1F50h sub 1 (DOMAIN, wo): program 1's data, by block download only (CiA 301
    §7.2.4.3.9-13: initiate C6h/C4h/C2h/C0h, segments of 7 bytes, blocks of 127, end C1h-DDh);
    other transfers of it are aborted with 0504 0001.
  - 1F51h sub 1 (UNSIGNED8, rw): program control: 0 stop, 1 start, 2 reset (DSP 302 §9), 3
    clear (CiA 302-3). With --refuse-clear, 3 is refused with 0609 0030 (value range
    exceeded), as a device built to DSP 302 v3.2.1 (range 0..2) does.
  - 1F52h sub 1/2 (UNSIGNED32, ro): the application's date (days since 1984-01-01) and time
    (ms after midnight); 2025-08-01 07:30 (15188, 27000000) until a downloaded program starts,
    then the version of its trailer (our convention: the image ends in date LE32, time LE32,
    "CPV1"), or 0/0 for an image without one.
  - 1F56h sub 1 (UNSIGNED32, ro): CiA 302-3's program software identification: 0BAD0001h until a
    downloaded program starts, then the image's CRC-32 (zlib's).
  - 1F57h sub 1 (UNSIGNED32, ro): CiA 302-3's flash status identification: after an image is
    stored, bit 0 ("in progress") for the first N reads (--flash-busy N, default 0), then 0
    (no error).
Extra lines: PROGRAM NODE SIZE (an image stored), CONTROL NODE VALUE (1F51h written), FLASH
NODE VALUE (1F57h read).
"""
import sys
import zlib

import master_slaves as base

TRAILER = b"CPV1"
REFUSE_CLEAR = False
FLASH_BUSY = 0


class ProgramSlave(base.Slave):
    def __init__(self, bus, node):
        super().__init__(bus, node)
        self.version = (15188, 27000000)
        self.control = 1
        self.image = None
        self.identification = 0x0BAD0001
        self.busy_reads = 0
        self.receiving = None  # block download: {"data", "size", "seq"}

    def version_of(self, image):
        if len(image) >= 12 and image[-4:] == TRAILER:
            return (int.from_bytes(image[-12:-8], "little"), int.from_bytes(image[-8:-4], "little"))
        return (0, 0)

    def reply(self, data):
        self.send(0x580 + self.node, list(data) + [0] * (8 - len(data)))

    def block_segment(self, data):
        r = self.receiving
        if r["end"]:
            if data[0] & 0xE3 != 0xC1:  # end request: ccs 6, cs 1, n in bits 2-4
                self.receiving = None
                self.abort(0x1F50, 1, 0x05040001)
                return
            unused = data[0] >> 2 & 0x07
            image = bytes(r["data"][: len(r["data"]) - unused])
            self.receiving = None
            if r["size"] is not None and len(image) != r["size"]:
                self.abort(0x1F50, 1, 0x06070010)
                return
            self.image = image
            self.busy_reads = FLASH_BUSY
            base.say("PROGRAM %d %d" % (self.node, len(image)))
            self.reply([0xA1])
            return
        seqno, last = data[0] & 0x7F, data[0] & 0x80
        if seqno == r["seq"] + 1:
            r["seq"] = seqno
            r["data"] += bytes(data[1:8])
        if seqno == 127 or last:
            self.reply([0xA2, r["seq"], 127])
            r["seq"] = 0
            r["end"] = bool(last)

    def sdo(self, data, now):
        if self.state == base.STOPPED or len(data) != 8:
            return
        if self.receiving is not None:
            self.block_segment(data)
            return
        command, index, sub = data[0], data[1] | data[2] << 8, data[3]
        ccs = command >> 5
        if index == 0x1F50 and sub == 1:
            if ccs == 6 and command & 0x01 == 0:  # block download initiate
                size = int.from_bytes(bytes(data[4:8]), "little") if command & 0x02 else None
                self.receiving = {"data": bytearray(), "size": size, "seq": 0, "end": False}
                self.reply([0xA0, data[1], data[2], sub, 127])  # no CRC (sc = 0)
            else:
                self.abort(index, sub, 0x05040001)
            return
        if index == 0x1F51 and sub == 1:
            if ccs == 2:
                self.reply([0x4F, data[1], data[2], sub, self.control])
                return
            if ccs != 1 or not command & 0x02:
                self.abort(index, sub, 0x05040001)
                return
            value = data[4]
            base.say("CONTROL %d %d" % (self.node, value))
            if value > (2 if REFUSE_CLEAR else 3):
                self.abort(index, sub, 0x06090030)
                return
            if value == 3:
                self.image = None
            self.control = value
            if value == 1 and self.image is not None:
                self.version = self.version_of(self.image)
                self.identification = zlib.crc32(self.image) & 0xFFFFFFFF
            self.reply([0x60, data[1], data[2], sub])
            return
        if index == 0x1F52 and sub in (1, 2):
            if ccs != 2:
                self.abort(index, sub, 0x06010002)
                return
            base.say("READ %d 1F52 %02X" % (self.node, sub))
            value = self.version[sub - 1].to_bytes(4, "little")
            self.reply([0x43, data[1], data[2], sub] + list(value))
            return
        if index in (0x1F56, 0x1F57) and sub == 1:
            if ccs != 2:
                self.abort(index, sub, 0x06010002)
                return
            if index == 0x1F56:
                value = self.identification
                base.say("READ %d 1F56 01" % self.node)
            else:
                value = 1 if self.busy_reads > 0 else 0
                self.busy_reads = max(0, self.busy_reads - 1)
                base.say("FLASH %d %d" % (self.node, value))
            self.reply([0x43, data[1], data[2], sub] + list(value.to_bytes(4, "little")))
            return
        if index == 0x1F52 and sub == 0 and ccs == 2:
            self.reply([0x4F, data[1], data[2], 0, 2])
            return
        super().sdo(data, now)


if __name__ == "__main__":
    argv = list(sys.argv)
    if len(argv) > 1 and argv[1] == "--refuse-clear":
        REFUSE_CLEAR = True
        del argv[1]
    if len(argv) > 2 and argv[1] == "--flash-busy":
        FLASH_BUSY = int(argv[2])
        del argv[1:3]
    base.Slave = ProgramSlave
    sys.exit(base.main(argv))
