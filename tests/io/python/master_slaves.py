#!/usr/bin/python3
"""CANopen slaves written with python-can alone: the independent peers of the NMT master test
(tests/io/udp_master_test.cpp) on the UDP multicast bus. Nothing here uses our C++ code.

Usage: master_slaves.py GROUP PORT TIMEOUT_S NODE...

Every NODE is a small CiA 301 slave:
  - NMT (CiA 301 §7.2.8.3.1): 01h start, 02h stop, 80h enter pre-operational, 81h reset node,
    82h reset communication, for its node-ID or for all (node-ID 0). A reset ends with the
    boot-up message 700h+node#00 and the state pre-operational.
  - an SDO server for expedited transfers (CiA 301 §7.2.4.3.3-6) on 600h+node / 580h+node;
    aborts (CiA 301 Table 22): 0504 0001 other commands (segmented, block), 0601 0002 write of
    a read-only object, 0602 0000 no such object, 0609 0011 no such sub-index, 0607 0010 wrong
    length, 0800 0020 1010h without the signature "save".
  - a heartbeat producer (1017h, ms) on 700h+node with the NMT state byte.
  - 1010h sub 1 "save" keeps the values; reset node and reset communication reload the kept ones
    (else the defaults). A write of any object but 1010h and 1020h sets 1020h sub 1 and 2 to 0
    (CiA 302 §6.3: the configuration is no longer the one 1020h names).

It prints READY once the bus is open and the first boot-up messages are out, then one line per
event, flushed:
  NMT NODE CS                  an NMT command for the node (CS in hex)
  READ NODE INDEX SUB          an SDO upload it answered
  WRITE NODE INDEX SUB DATA    an SDO download it stored (DATA in hex, little-endian as sent)
  SAVE NODE                    1010h sub 1 "save"
and ends with END on the frame 7FFh with no data (sent by the test), or TIMEOUT after TIMEOUT_S
(exit 1).
"""
import sys
import time

import can

PRE_OPERATIONAL, OPERATIONAL, STOPPED = 0x7F, 0x05, 0x04
SAVE = 0x65766173  # "save", CiA 301 §7.5.2.13


def objects_of(node):
    """The dictionary: (index, sub) -> [access, size, value]."""
    return {
        (0x1000, 0): ["ro", 4, 0x000F0191],  # CiA 401 device type
        (0x1001, 0): ["ro", 1, 0],
        (0x1010, 0): ["ro", 1, 1],
        (0x1010, 1): ["rw", 4, 1],
        (0x1017, 0): ["rw", 2, 100],
        (0x1018, 0): ["ro", 1, 4],
        (0x1018, 1): ["ro", 4, 0x7E57C0DE],
        (0x1018, 2): ["ro", 4, 0x00000401],
        (0x1018, 3): ["ro", 4, 0x00010002],
        (0x1018, 4): ["ro", 4, 0x5E000000 + node],
        (0x1020, 0): ["ro", 1, 2],
        (0x1020, 1): ["rw", 4, 0],
        (0x1020, 2): ["rw", 4, 0],
        (0x2000, 0): ["rw", 4, 0],
        (0x2001, 0): ["rw", 2, 0],
        (0x2002, 0): ["rw", 1, 0],
    }


def say(text):
    print(text, flush=True)


class Slave:
    def __init__(self, bus, node):
        self.bus = bus
        self.node = node
        self.defaults = objects_of(node)
        self.saved = None
        self.values = {}
        self.state = PRE_OPERATIONAL
        self.next_heartbeat = None

    def send(self, cob_id, data):
        self.bus.send(can.Message(arbitration_id=cob_id, is_extended_id=False, data=data))

    def reset(self, now):
        source = self.saved if self.saved is not None else self.defaults
        self.values = {key: entry[2] for key, entry in source.items()}
        self.state = PRE_OPERATIONAL
        self.send(0x700 + self.node, [0x00])  # boot-up
        period = self.values[(0x1017, 0)]
        self.next_heartbeat = now + period / 1000.0 if period else None

    def wakeup(self):
        """When the slave next has something to send on its own (None: only when asked)."""
        return self.next_heartbeat

    def heartbeat(self, now):
        if self.next_heartbeat is not None and now >= self.next_heartbeat:
            self.send(0x700 + self.node, [self.state])
            self.next_heartbeat += self.values[(0x1017, 0)] / 1000.0

    def nmt(self, command, now):
        say("NMT %d %02X" % (self.node, command))
        if command == 0x01:
            self.state = OPERATIONAL
        elif command == 0x02:
            self.state = STOPPED
        elif command == 0x80:
            self.state = PRE_OPERATIONAL
        elif command in (0x81, 0x82):
            self.reset(now)

    def abort(self, index, sub, code):
        self.send(0x580 + self.node,
                  [0x80, index & 0xFF, index >> 8, sub] + list(code.to_bytes(4, "little")))

    def sdo(self, data, now):
        if self.state == STOPPED or len(data) != 8:
            return
        command, index, sub = data[0], data[1] | data[2] << 8, data[3]
        ccs = command >> 5
        if ccs not in (1, 2) or (ccs == 1 and not command & 0x02):
            self.abort(index, sub, 0x05040001)
            return
        entry = self.defaults.get((index, sub))
        if entry is None:
            has_object = any(i == index for i, _ in self.defaults)
            self.abort(index, sub, 0x06090011 if has_object else 0x06020000)
            return
        access, size, _ = entry
        if ccs == 2:  # initiate upload: expedited, size indicated
            say("READ %d %04X %02X" % (self.node, index, sub))
            value = self.values[(index, sub)].to_bytes(size, "little")
            self.send(0x580 + self.node,
                      [0x43 | (4 - size) << 2, data[1], data[2], sub] + list(value.ljust(4, b"\0")))
            return
        length = 4 - (command >> 2 & 0x03) if command & 0x01 else size
        if access == "ro":
            self.abort(index, sub, 0x06010002)
            return
        if length != size:
            self.abort(index, sub, 0x06070010)
            return
        value = int.from_bytes(bytes(data[4:4 + size]), "little")
        if index == 0x1010 and value != SAVE:
            self.abort(index, sub, 0x08000020)
            return
        say("WRITE %d %04X %02X %s" % (self.node, index, sub, bytes(data[4:4 + size]).hex().upper()))
        if index == 0x1010:
            say("SAVE %d" % self.node)
            self.saved = {key: [entry[0], entry[1], self.values[key]]
                          for key, entry in self.defaults.items()}
        else:
            self.values[(index, sub)] = value
            if index != 0x1020:
                self.values[(0x1020, 1)] = self.values[(0x1020, 2)] = 0
        self.send(0x580 + self.node, [0x60, data[1], data[2], sub, 0, 0, 0, 0])


def main(argv):
    group, port, timeout = argv[1], int(argv[2]), float(argv[3])
    nodes = [int(n) for n in argv[4:]]
    with can.Bus(interface="udp_multicast", channel=group, port=port) as bus:
        now = time.monotonic()
        slaves = {n: Slave(bus, n) for n in nodes}
        for slave in slaves.values():
            slave.reset(now)  # power-on
        say("READY")
        deadline = now + timeout
        while True:
            now = time.monotonic()
            if now >= deadline:
                say("TIMEOUT")
                return 1
            for slave in slaves.values():
                slave.heartbeat(now)
            due = [s.wakeup() for s in slaves.values() if s.wakeup() is not None]
            wait = max(0.0, min(due + [deadline]) - now)
            msg = bus.recv(wait)
            if msg is None or msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
                continue
            now = time.monotonic()
            if msg.arbitration_id == 0x7FF and msg.dlc == 0:
                say("END")
                return 0
            if msg.arbitration_id == 0x000 and msg.dlc == 2:
                for slave in slaves.values():
                    if msg.data[1] in (0, slave.node):
                        slave.nmt(msg.data[0], now)
            elif 0x601 <= msg.arbitration_id <= 0x67F:
                slave = slaves.get(msg.arbitration_id - 0x600)
                if slave is not None:
                    slave.sdo(msg.data, now)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
