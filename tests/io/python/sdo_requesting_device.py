#!/usr/bin/python3
"""An SDO requesting device (SRD) of CiA DSP 302 section 7, written with python-can alone from
the spec: the independent peer of the SDO manager test over the UDP multicast bus
(tests/tools/sdo_manager_udp_test.cpp). Nothing here uses our C++ code.

Usage: sdo_requesting_device.py GROUP PORT TIMEOUT_S NODE SLAVE [HOLD_S]

The device at NODE is a small CiA 301 slave with the SRD objects of DSP 302 section 7.2.3:
  - NMT (CiA 301 section 7.2.8.3.1) for its node-ID or all nodes; a reset (81h, 82h) restores
    the communication area (1000h-1FFFh: 1F10h, 1280h, 1281h) and sends the boot-up 700h+NODE#00.
  - heartbeat producer 1017h = 100 ms (section 7.2.1: a registered SRD takes part in error
    control).
  - an expedited SDO server (CiA 301 section 7.2.4.3.3-6) on 600h+NODE / 580h+NODE serving 1000h,
    1017h, 1018h, client SDO parameters 1280h and 1281h (sub 1, 2: COB-IDs, bit 31 = not valid;
    sub 3: the server's node-ID), 1F10h Dynamic SDO connection state (UNSIGNED32 rw) and 1F11h
    Slave failed (UNSIGNED16 wo).
And it does what section 7.2 asks of an SRD:
  1. Once the master started SLAVE (NMT start for it or for all), it sets 1F10h = 12800001h
     (OD index 1280h, Rq indication) and sends the Dynamic SDO Request: COB-ID 1760 (6E0h), a
     data frame without data bytes; again every 5 s while 1F10h still holds the request.
  2. When the manager wrote 1F10h with Cnxn state 1 (bits 2-1) and Rq indication 0, it sets 1F10h
     to 0 (registered: "the value has to be 0") and 300 ms later writes 1F00h (request SDO) =
     1281h << 16 | NODE << 8 | SLAVE to the manager over the client entry 1280h the manager
     filled in.
  3. When the manager wrote 1F10h with Cnxn state 3 and index 1281h, it reads SLAVE's 1018h sub 1
     over the client entry 1281h, keeps the connection HOLD_S seconds (default 0: another
     SRD's request meanwhile finds SLAVE's default SDO taken), then writes 1F01h (release SDO) = 1281h << 16 | NODE << 8 | SLAVE
     over 1280h and waits until the manager set bit 31 of 1281h sub 1.

It prints READY once the bus is open and its boot-up is out, then one line per event, flushed:
  WRITE INDEX SUB VALUE        an SDO download it stored (hex, the value as a number)
  REQUEST                      it set 1F10h and sent 6E0h
  REGISTERED INDEX COB1 COB2 NODE   the manager confirmed; the client entry (hex)
  REQUESTED                    the manager accepted the 1F00h write
  CONNECTED INDEX COB1 COB2 NODE    the manager confirmed the connection; the client entry
  READ INDEX SUB VALUE         the upload over the connection (hex)
  RELEASE                      the manager accepted the 1F01h write
  RELEASED INDEX               the manager invalidated the client entry
  REFUSED INDEX CODE / FAILED TEXT  an abort or a 1F10h with Cnxn state 0 (exit 1)
and ends with END (exit 0), or TIMEOUT after TIMEOUT_S (exit 1).
"""
import sys
import time

import can

PRE_OPERATIONAL, OPERATIONAL, STOPPED = 0x7F, 0x05, 0x04
NOT_VALID = 0x80000000
REQUEST_ID = 0x6E0  # 1760 decimal, DSP 302 section 7.2.1


def objects_of():
    """The dictionary: (index, sub) -> [access, size, default]."""
    return {
        (0x1000, 0): ["ro", 4, 0x00000000],
        (0x1001, 0): ["ro", 1, 0],
        (0x1017, 0): ["rw", 2, 100],
        (0x1018, 0): ["ro", 1, 4],
        (0x1018, 1): ["ro", 4, 0x0000ABCD],
        (0x1018, 2): ["ro", 4, 0x00000007],
        (0x1018, 3): ["ro", 4, 0x00010000],
        (0x1018, 4): ["ro", 4, 0x00000001],
        (0x1280, 0): ["ro", 1, 3],
        (0x1280, 1): ["rw", 4, NOT_VALID],
        (0x1280, 2): ["rw", 4, NOT_VALID],
        (0x1280, 3): ["rw", 1, 0],
        (0x1281, 0): ["ro", 1, 3],
        (0x1281, 1): ["rw", 4, NOT_VALID],
        (0x1281, 2): ["rw", 4, NOT_VALID],
        (0x1281, 3): ["rw", 1, 0],
        (0x1F10, 0): ["rw", 4, 0],
        (0x1F11, 0): ["wo", 2, 0],
    }


def say(text):
    print(text, flush=True)


class Srd:
    def __init__(self, bus, node, slave, hold):
        self.bus = bus
        self.node = node
        self.slave = slave
        self.hold = hold
        self.release_at = None
        self.objects = objects_of()
        self.values = {}
        self.state = PRE_OPERATIONAL
        self.next_heartbeat = None
        self.phase = "wait-start"  # wait-start, registering, registered, requesting, connecting,
        # reading, holding, releasing
        self.next_request = None
        self.request_at = None
        self.pending = None  # (cob_id_response, what) of our own client transfer
        self.failed = False
        self.done = False

    def send(self, cob_id, data):
        self.bus.send(can.Message(arbitration_id=cob_id, is_extended_id=False, data=data))

    def reset(self, now):
        self.values = {key: entry[2] for key, entry in self.objects.items()}
        self.state = PRE_OPERATIONAL
        self.send(0x700 + self.node, [0x00])
        self.next_heartbeat = now + self.values[(0x1017, 0)] / 1000.0

    def heartbeat(self, now):
        if self.next_heartbeat is not None and now >= self.next_heartbeat:
            self.send(0x700 + self.node, [self.state])
            self.next_heartbeat += self.values[(0x1017, 0)] / 1000.0

    def nmt(self, command, target, now):
        if target == self.slave or target == 0:
            if command == 0x01 and self.phase == "wait-start":
                self.start_registration(now)
        if target not in (0, self.node):
            return
        if command == 0x01:
            self.state = OPERATIONAL
        elif command == 0x02:
            self.state = STOPPED
        elif command == 0x80:
            self.state = PRE_OPERATIONAL
        elif command in (0x81, 0x82):
            self.reset(now)

    def start_registration(self, now):
        # Section 7.2.3: xxxx0001h, xxxx = the OD index of a free client SDO entry.
        self.values[(0x1F10, 0)] = 0x1280 << 16 | 0x0001
        self.send(REQUEST_ID, [])
        say("REQUEST")
        self.phase = "registering"
        self.next_request = now + 5.0

    def tick(self, now):
        self.heartbeat(now)
        if self.phase == "holding" and now >= self.release_at:
            # Section 7.2.3 1F01h: release the connection on 1281h to the slave.
            self.client_download(0x1280, 0x1F01, 0, 0x1281 << 16 | self.node << 8 | self.slave,
                                 "release")
            self.phase = "releasing"
        if self.phase == "registered" and now >= self.request_at:
            # Section 7.2.2: 1F00h = index << 16 | SRD << 8 | slave, over the new channel.
            self.client_download(0x1280, 0x1F00, 0, 0x1281 << 16 | self.node << 8 | self.slave,
                                 "request")
            self.phase = "requesting"
        if self.phase == "registering" and now >= self.next_request:
            if self.values[(0x1F10, 0)] & 0x1:
                self.send(REQUEST_ID, [])
                say("REQUEST")
            self.next_request = now + 5.0

    # --- the SDO server on the default SDO -------------------------------------------------
    def abort(self, index, sub, code):
        self.send(0x580 + self.node,
                  [0x80, index & 0xFF, index >> 8, sub] + list(code.to_bytes(4, "little")))

    def serve(self, data, now):
        if self.state == STOPPED or len(data) != 8:
            return
        command, index, sub = data[0], data[1] | data[2] << 8, data[3]
        ccs = command >> 5
        if ccs == 4:  # abort from the client
            return
        if ccs not in (1, 2) or (ccs == 1 and not command & 0x02):
            self.abort(index, sub, 0x05040001)
            return
        entry = self.objects.get((index, sub))
        if entry is None:
            has_object = any(i == index for i, _ in self.objects)
            self.abort(index, sub, 0x06090011 if has_object else 0x06020000)
            return
        access, size, _ = entry
        if ccs == 2:
            if access == "wo":
                self.abort(index, sub, 0x06010001)
                return
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
        self.values[(index, sub)] = value
        say("WRITE %04X %02X %08X" % (index, sub, value))
        self.send(0x580 + self.node, [0x60, data[1], data[2], sub, 0, 0, 0, 0])
        self.written(index, sub, value, now)

    def entry_text(self, index):
        return "%04X %08X %08X %02X" % (index, self.values[(index, 1)], self.values[(index, 2)],
                                        self.values[(index, 3)])

    def written(self, index, sub, value, now):
        if index == 0x1281 and sub == 1 and value & NOT_VALID and self.phase == "releasing":
            say("RELEASED 1281")
            self.done = True
            return
        if index != 0x1F10:
            return
        cnxn, rq, error, od_index = value >> 1 & 3, value & 1, value >> 8 & 0xFF, value >> 16
        if cnxn == 0 and not rq:
            say("FAILED 1F10h = %08X (error code %02X)" % (value, error))
            self.failed = True
        elif self.phase == "registering" and cnxn == 1 and not rq:
            say("REGISTERED " + self.entry_text(od_index))
            self.values[(0x1F10, 0)] = 0
            # The application asks for its connection a moment later (the simulated-bus suite
            # checks a request right after the confirmation).
            self.request_at = now + 0.3
            self.phase = "registered"
        elif self.phase in ("requesting", "connecting") and cnxn == 3 and od_index == 0x1281:
            say("CONNECTED " + self.entry_text(0x1281))
            self.values[(0x1F10, 0)] = 0
            self.client_upload(0x1281, 0x1018, 1)
            self.phase = "reading"

    # --- the client side, over the entries the manager wrote ------------------------------
    def client_download(self, entry, index, sub, value, what):
        request, response = self.values[(entry, 1)], self.values[(entry, 2)]
        self.pending = (response & 0x7FF, what, index, sub)
        self.send(request & 0x7FF,
                  [0x23, index & 0xFF, index >> 8, sub] + list(value.to_bytes(4, "little")))

    def client_upload(self, entry, index, sub):
        request, response = self.values[(entry, 1)], self.values[(entry, 2)]
        self.pending = (response & 0x7FF, "read", index, sub)
        self.send(request & 0x7FF, [0x40, index & 0xFF, index >> 8, sub, 0, 0, 0, 0])

    def response(self, data):
        _, what, index, sub = self.pending
        self.pending = None
        if data[0] == 0x80:
            say("REFUSED %04X %08X" % (index, int.from_bytes(bytes(data[4:8]), "little")))
            self.failed = True
            return
        if what == "request" and data[0] == 0x60:
            say("REQUESTED")
            if self.phase == "requesting":
                self.phase = "connecting"
        elif what == "read" and data[0] & 0xE3 == 0x43:
            size = 4 - (data[0] >> 2 & 3)
            value = int.from_bytes(bytes(data[4:4 + size]), "little")
            say("READ %04X %02X %08X" % (index, sub, value))
            self.release_at = time.monotonic() + self.hold
            self.phase = "holding"
        elif what == "release" and data[0] == 0x60:
            say("RELEASE")
        else:
            say("FAILED unexpected response %s" % bytes(data).hex())
            self.failed = True


def main(argv):
    group, port, timeout = argv[1], int(argv[2]), float(argv[3])
    node, slave = int(argv[4]), int(argv[5])
    hold = float(argv[6]) if len(argv) > 6 else 0.0
    with can.Bus(interface="udp_multicast", channel=group, port=port) as bus:
        now = time.monotonic()
        srd = Srd(bus, node, slave, hold)
        srd.reset(now)
        say("READY")
        deadline = now + timeout
        while True:
            now = time.monotonic()
            if srd.failed:
                return 1
            if srd.done:
                say("END")
                return 0
            if now >= deadline:
                say("TIMEOUT")
                return 1
            srd.tick(now)
            msg = bus.recv(0.02)
            if msg is None or msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
                continue
            now = time.monotonic()
            if msg.arbitration_id == 0x000 and msg.dlc == 2:
                srd.nmt(msg.data[0], msg.data[1], now)
            elif msg.arbitration_id == 0x600 + node:
                srd.serve(msg.data, now)
            elif srd.pending is not None and msg.arbitration_id == srd.pending[0] and msg.dlc == 8:
                srd.response(msg.data)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
