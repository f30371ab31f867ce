#!/usr/bin/python3
"""master_slaves.py's slaves with an emergency producer, written with python-can alone (nothing
here uses our C++ code): the independent peers of the EMCY tests over the UDP multicast bus
(tests/tools/emcy_udp_test.cpp).

Usage: emcy_slaves.py [--emcy NODE:TRIGGER:DELAY_MS:CODE:REGISTER[:MANUFACTURER]]... GROUP PORT
       TIMEOUT_S NODE...

Besides master_slaves.py's objects, every NODE has 1014h (UNSIGNED32, rw), the COB-ID of its
EMCY (CiA 301 §7.5.2.17): 80h + node-ID at power-on (the pre-defined connection set, CiA 301
§7.3.5), bit 31 set means "no EMCY", bits 0-10 the CAN-ID. A download of 1014h is kept like any
other entry, so an EMCY goes on the COB-ID the master configured; one that changes the CAN-ID
while bit 31 is clear in both the old and the new value is refused with 0609 0030 (§7.5.2.17).

Each --emcy schedules one emergency message of NODE, DELAY_MS after TRIGGER:
  boot          the power-on boot-up message
  start         each NMT start (01h) of the node
  write-XXXX    each download of object XXXX (hex) the node answered
CODE (hex, 16 bits), REGISTER (hex, 1001h's byte) and MANUFACTURER (hex, up to 5 bytes, default
00...) make the 8 data bytes of CiA 301 §7.2.7.3.1: the error code little-endian, the error
register, the manufacturer-specific field. An EMCY due while 1014h bit 31 is set, or while the
node is stopped (CiA 301 Table 83: no EMCY in stopped), is not sent and says so.

Extra lines: EMCY NODE COBID CODE (one sent; hex), NOEMCY NODE CODE (one not sent).
"""
import sys

import master_slaves as base

SCHEDULE = []  # (node, trigger, delay_s, data)


def parse_emcy(text):
    parts = text.split(":")
    if len(parts) not in (5, 6):
        raise SystemExit("--emcy NODE:TRIGGER:DELAY_MS:CODE:REGISTER[:MANUFACTURER], got " + text)
    node, trigger, delay = int(parts[0]), parts[1], int(parts[2]) / 1000.0
    code, register = int(parts[3], 16), int(parts[4], 16)
    manufacturer = bytes.fromhex(parts[5]) if len(parts) == 6 else b""
    if len(manufacturer) > 5:
        raise SystemExit("at most 5 manufacturer bytes: " + text)
    data = list(code.to_bytes(2, "little")) + [register] + list(manufacturer.ljust(5, b"\0"))
    return (node, trigger, delay, data)


class EmcySlave(base.Slave):
    def __init__(self, bus, node):
        super().__init__(bus, node)
        self.defaults[(0x1014, 0)] = ["rw", 4, 0x80 + node]
        self.due = []  # (time, data)
        self.powered = False

    def trigger(self, name, now):
        for node, trigger, delay, data in SCHEDULE:
            if node == self.node and trigger == name:
                self.due.append((now + delay, data))
        self.due.sort(key=lambda d: d[0])

    def wakeup(self):
        times = [t for t in (self.next_heartbeat, self.due[0][0] if self.due else None)
                 if t is not None]
        return min(times) if times else None

    def heartbeat(self, now):
        super().heartbeat(now)
        while self.due and self.due[0][0] <= now:
            _, data = self.due.pop(0)
            cob_id = self.values[(0x1014, 0)]
            code = data[0] | data[1] << 8
            if cob_id & 0x80000000 or self.state == base.STOPPED:
                base.say("NOEMCY %d %04X" % (self.node, code))
                continue
            self.send(cob_id & 0x7FF, data)
            base.say("EMCY %d %03X %04X" % (self.node, cob_id & 0x7FF, code))

    def reset(self, now):
        super().reset(now)
        if not self.powered:
            self.powered = True
            self.trigger("boot", now)

    def nmt(self, command, now):
        super().nmt(command, now)
        if command == 0x01:
            self.trigger("start", now)

    def sdo(self, data, now):
        if len(data) == 8 and data[0] >> 5 == 1 and data[1] | data[2] << 8 == 0x1014:
            # CiA 301 §7.5.2.17: bits 0-29 may change only while bit 31 is set (EMCY not valid).
            current = self.values[(0x1014, 0)]
            written = int.from_bytes(bytes(data[4:8]), "little")
            if not current & 0x80000000 and not written & 0x80000000 and written != current:
                self.abort(0x1014, data[3], 0x06090030)
                return
        super().sdo(data, now)
        command = data[0] if len(data) == 8 else 0
        if command >> 5 == 1:  # a download; whether it was taken is not asked here
            index = data[1] | data[2] << 8
            self.trigger("write-%04X" % index, now)


if __name__ == "__main__":
    argv = [sys.argv[0]]
    args = sys.argv[1:]
    while args:
        if args[0] == "--emcy" and len(args) > 1:
            SCHEDULE.append(parse_emcy(args[1]))
            args = args[2:]
        else:
            argv.append(args.pop(0))
    base.Slave = EmcySlave
    sys.exit(base.main(argv))
