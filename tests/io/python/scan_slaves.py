#!/usr/bin/python3
"""The devices of `cfgmgr scan`'s end-to-end test over the UDP multicast bus
(tests/tools/scan_udp_test.cpp), written with python-can alone on master_slaves.py's Slave
(nothing here uses our C++ code). The EDS files of tests/data/scan/eds describe them.

Usage: scan_slaves.py [--factory] [--serial BASE] GROUP PORT TIMEOUT_S KIND@NODE... [lss]

Without --factory each device holds the values it was found with on a running machine (the
"as found" state: a configured machine); with --factory it holds its factory defaults, the
DefaultValues of its EDS (a replacement device out of the box). 1018h sub 4 (serial number) is
BASE + node-ID (hex, default 5E000000h): a replacement has another serial number.

KIND (vendor-ID C0FFEEh unless said):
  drive      product 2001h, revision 00020001h: UNSIGNED8/16/32, INTEGER8/16/32 and
             VISIBLE_STRING rw entries (2005h of 12 characters as found: segmented transfers;
             2006h of 3: expedited), an ARRAY, 1014h, 1017h, RPDO1 (1400h/1600h), TPDO1/TPDO2
             (1800h/1A00h, 1801h/1A01h), CiA 402's 6040h/6060h/607Ah/60FFh; as found RPDO1 and
             TPDO1 have other mappings, TPDO1 another transmission type and inhibit time, TPDO2
             is disabled (1801h sub 1 bit 31). Also entries the scan must not read: 1010h/1011h
             sub 1 (store, restore), 2007h (DOMAIN), 2009h (ro), 200Ah (wo), 1008h (const).
  drive_old  the drive's product at revision 00010003h, older than any EDS of it.
  io         product 2002h of the same vendor, which no EDS describes.
  foreign    vendor-ID BADBADh, product 1h: no EDS of the vendor at all.
  sensor     product 3001h, revision 00010000h, whose EDS lists 2101h and 2102h rw: the device
             has no 2101h (abort 0602 0000) and refuses reads of 2102h (0601 0000; writes go).
  lss        (no @NODE) a device without node-ID (FFh) that answers CiA 305 Fastscan and
             switch state global/selective; LSS address C0FFEEh:2001h:00020001h:BASE+99h.

Protocols (CiA 301): NMT as master_slaves.py; SDO expedited and segmented upload and download
(§7.2.4.3.3-8; aborts of Table 22: 0503 0000 toggle bit, 0504 0001 other commands (block),
0601 0001 read of a wo entry, 0601 0002 write of a ro one, 0602 0000, 0609 0011, 0607 0010
wrong length, 0607 0012 string too long, 0800 0020 1010h/1011h without "save"/"load"); PDO
parameters as §7.5.2.35-38 allow them: a valid PDO's COB-ID cannot be changed to another valid
one (0609 0030); its mapping sub 0 cannot be written while the PDO is valid, nor a mapping entry
while sub 0 is not 0 (0800 0022); a mapping of an object that does not exist, or of more than
64 bits, is refused (0604 0041, 0604 0042). LSS (CiA 305): 04h switch state global, 40h-43h
switch state selective (44h), 4Ch identify non-configured (50h), 51h Fastscan (4Fh), 5Ah-5Eh
inquire, 11h configure node-ID, 17h store, as libnmt's LSS slave answers them.

Lines, flushed: READY; NMT NODE CS; READ NODE INDEX SUB (an upload answered with data);
REFUSED NODE INDEX SUB CODE up|down|other (an upload, a download or another request aborted);
WRITE NODE INDEX SUB DATA (a download stored, DATA hex as sent); SAVE NODE; LSS TEXT (LSS
services, e.g. "LSS FASTSCAN FOUND"). On the frame 7FFh with no data: DUMP NODE INDEX SUB DATA for every entry a read is
answered for, then END (exit 0); TIMEOUT after TIMEOUT_S (exit 1).
"""
import sys
import time

import can

import master_slaves as base

VENDOR = 0x00C0FFEE
SIZES = {"u8": 1, "u16": 2, "u32": 4, "i8": 1, "i16": 2, "i32": 4}
LOAD = 0x64616F6C  # "load", CiA 301 §7.5.2.14
MAX_STRING = 24


def le(kind, value):
    if kind in ("vs", "domain"):
        return value.encode("ascii") if isinstance(value, str) else bytes(value)
    return (value & (1 << 8 * SIZES[kind]) - 1).to_bytes(SIZES[kind], "little")


class Entry:
    """One sub-object: access (ro, const, rw, wo), kind (u8..i32, vs, domain), factory value,
    as-found value (None: the factory one), and the abort a read gets (None: answered)."""

    def __init__(self, access, kind, factory, found=None, refuse_read=None):
        self.access, self.kind = access, kind
        self.factory = le(kind, factory)
        self.found = self.factory if found is None else le(kind, found)
        self.refuse_read = refuse_read


def common(node, device_type, vendor, product, revision, serial, heartbeat):
    return {
        (0x1000, 0): Entry("ro", "u32", device_type),
        (0x1001, 0): Entry("ro", "u8", 0),
        (0x1017, 0): Entry("rw", "u16", 0, heartbeat),
        (0x1018, 0): Entry("ro", "u8", 4),
        (0x1018, 1): Entry("ro", "u32", vendor),
        (0x1018, 2): Entry("ro", "u32", product),
        (0x1018, 3): Entry("ro", "u32", revision),
        (0x1018, 4): Entry("ro", "u32", serial),
    }


def drive(node, serial, revision=0x00020001):
    d = common(node, 0x00020192, VENDOR, 0x2001, revision, serial, 250)
    d.update({
        (0x1008, 0): Entry("const", "vs", "SD-2001 drive"),
        (0x1010, 0): Entry("ro", "u8", 1),
        (0x1010, 1): Entry("rw", "u32", 1),
        (0x1011, 0): Entry("ro", "u8", 1),
        (0x1011, 1): Entry("rw", "u32", 1),
        (0x1014, 0): Entry("rw", "u32", 0x80 + node),
        (0x1200, 0): Entry("ro", "u8", 2),
        (0x1200, 1): Entry("ro", "u32", 0x600 + node),
        (0x1200, 2): Entry("ro", "u32", 0x580 + node),
        # RPDO1: controlword + target position; as found controlword, target velocity, mode.
        (0x1400, 0): Entry("ro", "u8", 2),
        (0x1400, 1): Entry("rw", "u32", 0x200 + node),
        (0x1400, 2): Entry("rw", "u8", 0xFF, 0x01),
        (0x1600, 0): Entry("rw", "u8", 2, 3),
        (0x1600, 1): Entry("rw", "u32", 0x60400010),
        (0x1600, 2): Entry("rw", "u32", 0x607A0020, 0x60FF0020),
        (0x1600, 3): Entry("rw", "u32", 0, 0x60600008),
        (0x1600, 4): Entry("rw", "u32", 0),
        # TPDO1: statusword + position actual; as found statusword + velocity actual, sync.
        (0x1800, 0): Entry("ro", "u8", 5),
        (0x1800, 1): Entry("rw", "u32", 0x180 + node),
        (0x1800, 2): Entry("rw", "u8", 0xFF, 0x01),
        (0x1800, 3): Entry("rw", "u16", 0, 100),
        (0x1800, 5): Entry("rw", "u16", 0),
        (0x1A00, 0): Entry("rw", "u8", 2),
        (0x1A00, 1): Entry("rw", "u32", 0x60410010),
        (0x1A00, 2): Entry("rw", "u32", 0x60640020, 0x606C0020),
        (0x1A00, 3): Entry("rw", "u32", 0),
        (0x1A00, 4): Entry("rw", "u32", 0),
        # TPDO2: modes of operation display; disabled as found (bit 31).
        (0x1801, 0): Entry("ro", "u8", 5),
        (0x1801, 1): Entry("rw", "u32", 0x280 + node, 0x80000280 + node),
        (0x1801, 2): Entry("rw", "u8", 0xFF),
        (0x1801, 3): Entry("rw", "u16", 0),
        (0x1801, 5): Entry("rw", "u16", 0, 500),
        (0x1A01, 0): Entry("rw", "u8", 1),
        (0x1A01, 1): Entry("rw", "u32", 0x60610008),
        (0x1A01, 2): Entry("rw", "u32", 0),
        (0x2000, 0): Entry("rw", "u8", 5, 17),
        (0x2001, 0): Entry("rw", "u16", 1000, 2500),
        (0x2002, 0): Entry("rw", "u32", 0x00010000, 0xDEADBEEF),
        (0x2003, 0): Entry("rw", "i16", 0, -300),
        (0x2004, 0): Entry("rw", "i32", -1, -2000000),
        (0x2005, 0): Entry("rw", "vs", "factory", "AXIS_LEFT_01"),
        (0x2006, 0): Entry("rw", "vs", "ab", "XYZ"),
        (0x2007, 0): Entry("rw", "domain", b"\x01\x02\x03\x04\x05\x06\x07\x08\x09"),
        (0x2008, 0): Entry("ro", "u8", 2),
        (0x2008, 1): Entry("rw", "u16", 10, 11),
        (0x2008, 2): Entry("rw", "u16", 20, 22),
        (0x2009, 0): Entry("ro", "u32", 0x12345678),
        (0x200A, 0): Entry("wo", "u8", 0),
        (0x200B, 0): Entry("rw", "u16", 7, 70),
        (0x6040, 0): Entry("rw", "u16", 0, 0x000F),
        (0x6041, 0): Entry("ro", "u16", 0x0250),
        (0x6060, 0): Entry("rw", "i8", 0, 3),
        (0x6061, 0): Entry("ro", "i8", 0),
        (0x6064, 0): Entry("ro", "i32", 0),
        (0x606C, 0): Entry("ro", "i32", 0),
        (0x607A, 0): Entry("rw", "i32", 0, -1000),
        (0x60FF, 0): Entry("rw", "i32", 0, 1500),
    })
    return d


def drive_old(node, serial):
    return drive(node, serial, revision=0x00010003)


def plain(node, serial, vendor, product):
    d = common(node, 0x000F0191, vendor, product, 0x00010000, serial, 200)
    d.update({
        (0x2000, 0): Entry("rw", "u32", 0, 0x0BADCAFE),
        (0x2001, 0): Entry("rw", "u8", 1, 9),
    })
    return d


def io(node, serial):
    return plain(node, serial, VENDOR, 0x2002)


def foreign(node, serial):
    return plain(node, serial, 0x00BADBAD, 0x0001)


def sensor(node, serial):
    d = common(node, 0x00000194, VENDOR, 0x3001, 0x00010000, serial, 300)
    d.update({
        (0x2100, 0): Entry("rw", "u16", 100, 640),
        # 2101h: the EDS lists it, this firmware has none (0602 0000).
        (0x2102, 0): Entry("rw", "u8", 0, 0x5A, refuse_read=0x06010000),
        (0x2103, 0): Entry("rw", "i16", 0, -12),
        (0x2104, 0): Entry("rw", "vs", "sensor", "sensor-0001"),
    })
    return d


KINDS = {"drive": drive, "drive_old": drive_old, "io": io, "foreign": foreign, "sensor": sensor}


def pdo_mapping_of(comm):
    return comm + 0x200  # 1400h -> 1600h, 1800h -> 1A00h


class ScanSlave(base.Slave):
    def __init__(self, bus, node, entries, factory):
        self.entries = entries
        self.factory = factory
        self.transfer = None  # a segmented transfer: {"up", "key", "data", "toggle", ...}
        super().__init__(bus, node)

    def reset(self, now):
        self.values = {k: (e.factory if self.factory else e.found) for k, e in self.entries.items()}
        if self.saved is not None:
            self.values.update(self.saved)
        self.transfer = None
        self.state = base.PRE_OPERATIONAL
        self.send(0x700 + self.node, [0x00])
        period = self.heartbeat_period()
        self.next_heartbeat = now + period / 1000.0 if period else None

    def heartbeat_period(self):
        return int.from_bytes(self.values[(0x1017, 0)], "little")

    def heartbeat(self, now):
        if self.next_heartbeat is None:
            return
        period = self.heartbeat_period()
        if period == 0:
            self.next_heartbeat = None
        elif now >= self.next_heartbeat:
            self.send(0x700 + self.node, [self.state])
            self.next_heartbeat = max(self.next_heartbeat + period / 1000.0, now)

    def refuse(self, index, sub, code, what):
        base.say("REFUSED %d %04X %02X %08X %s" % (self.node, index, sub, code, what))
        self.transfer = None
        self.abort(index, sub, code)

    def reply(self, data):
        self.send(0x580 + self.node, list(data) + [0] * (8 - len(data)))

    def u32(self, key):
        return int.from_bytes(self.values[key], "little")

    def lookup(self, index, sub):
        """The entry, or the abort code."""
        entry = self.entries.get((index, sub))
        if entry is not None:
            return entry, None
        return None, 0x06090011 if any(i == index for i, _ in self.entries) else 0x06020000

    # --- upload -------------------------------------------------------------------------------
    def upload(self, data, index, sub):
        entry, code = self.lookup(index, sub)
        if entry is None:
            return self.refuse(index, sub, code, "up")
        if entry.access == "wo":
            return self.refuse(index, sub, 0x06010001, "up")
        if entry.refuse_read is not None:
            return self.refuse(index, sub, entry.refuse_read, "up")
        base.say("READ %d %04X %02X" % (self.node, index, sub))
        value = self.values[(index, sub)]
        if len(value) <= 4:
            self.reply([0x43 | (4 - len(value)) << 2, data[1], data[2], sub] + list(value))
        else:  # segmented: size indicated (§7.2.4.3.5)
            self.transfer = {"up": True, "key": (index, sub), "data": bytes(value), "toggle": 0}
            self.reply([0x41, data[1], data[2], sub] + list(len(value).to_bytes(4, "little")))

    def upload_segment(self, command):
        t = self.transfer
        index, sub = t["key"]
        if command >> 4 & 1 != t["toggle"]:
            return self.refuse(index, sub, 0x05030000, "up")
        chunk, t["data"] = t["data"][:7], t["data"][7:]
        last = not t["data"]
        self.reply([t["toggle"] << 4 | (7 - len(chunk)) << 1 | int(last)] + list(chunk))
        t["toggle"] ^= 1
        if last:
            self.transfer = None

    # --- download -----------------------------------------------------------------------------
    def download(self, data, index, sub):
        command = data[0]
        entry, code = self.lookup(index, sub)
        if entry is None:
            return self.refuse(index, sub, code, "down")
        if entry.access in ("ro", "const"):
            return self.refuse(index, sub, 0x06010002, "down")
        if command & 0x02:  # expedited
            n = 4 - (command >> 2 & 0x03) if command & 0x01 else 4
            value = bytes(data[4:4 + n])
            if self.store(index, sub, entry, value):
                self.reply([0x60, data[1], data[2], sub])
            return
        size = int.from_bytes(bytes(data[4:8]), "little") if command & 0x01 else None
        self.transfer = {"up": False, "key": (index, sub), "data": b"", "toggle": 0, "size": size}
        self.reply([0x60, data[1], data[2], sub])

    def download_segment(self, data):
        t = self.transfer
        index, sub = t["key"]
        command = data[0]
        if command >> 4 & 1 != t["toggle"]:
            return self.refuse(index, sub, 0x05030000, "down")
        n = command >> 1 & 0x07
        t["data"] += bytes(data[1:8 - n])
        toggle = t["toggle"]
        t["toggle"] ^= 1
        if command & 0x01:  # last segment
            self.transfer = None
            if t["size"] is not None and t["size"] != len(t["data"]):
                return self.refuse(index, sub, 0x06070010, "down")
            if not self.store(index, sub, self.entries[(index, sub)], t["data"]):
                return
        self.reply([0x20 | toggle << 4])

    def store(self, index, sub, entry, value):
        """Checks and stores a downloaded value; False when it was refused (abort sent)."""
        if entry.kind == "vs":
            if len(value) > MAX_STRING:
                self.refuse(index, sub, 0x06070012, "down")
                return False
        elif entry.kind != "domain" and len(value) != SIZES[entry.kind]:
            self.refuse(index, sub, 0x06070010, "down")
            return False
        number = int.from_bytes(value, "little")
        if index in (0x1010, 0x1011) and number != (base.SAVE if index == 0x1010 else LOAD):
            self.refuse(index, sub, 0x08000020, "down")
            return False
        code = self.pdo_rule(index, sub, number)
        if code:
            self.refuse(index, sub, code, "down")
            return False
        base.say("WRITE %d %04X %02X %s" % (self.node, index, sub, value.hex().upper()))
        if index == 0x1010:
            base.say("SAVE %d" % self.node)
            self.saved = {k: v for k, v in self.values.items() if self.entries[k].access == "rw"}
        elif index == 0x1011:
            self.saved = None
        else:
            self.values[(index, sub)] = value
            if index == 0x1017 and number and self.next_heartbeat is None:
                self.next_heartbeat = time.monotonic() + number / 1000.0
        return True

    def pdo_rule(self, index, sub, number):
        """CiA 301 §7.5.2.35-38: the abort code a PDO parameter's write gets, or 0."""
        if 0x1400 <= index <= 0x15FF or 0x1800 <= index <= 0x19FF:
            if sub != 1:
                return 0
            old = self.u32((index, 1))
            if not old >> 31 and not number >> 31 and (old ^ number) & 0x1FFFFFFF:
                return 0x06090030  # a valid PDO's CAN-ID cannot change
            return 0
        if 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF:
            comm = index - 0x200
            if sub == 0:
                if not self.u32((comm, 1)) >> 31:
                    return 0x08000022  # the PDO is valid
                bits = 0
                for i in range(1, number + 1):
                    if (index, i) not in self.entries:
                        return 0x06040042
                    mapped = self.u32((index, i))
                    if (mapped >> 16, mapped >> 8 & 0xFF) not in self.entries:
                        return 0x06040041
                    bits += mapped & 0xFF
                return 0x06040042 if bits > 64 else 0
            if self.u32((index, 0)) != 0:
                return 0x08000022  # sub 0 must be 0 while the mapping changes
            if number and (number >> 16, number >> 8 & 0xFF) not in self.entries:
                return 0x06040041
        return 0

    def sdo(self, data, now):
        if self.state == base.STOPPED or len(data) != 8:
            return
        command, index, sub = data[0], data[1] | data[2] << 8, data[3]
        ccs = command >> 5
        if ccs == 4:  # abort from the client
            self.transfer = None
            return
        if self.transfer is not None:
            if self.transfer["up"] and ccs == 3:
                return self.upload_segment(command)
            if not self.transfer["up"] and ccs == 0:
                return self.download_segment(data)
            self.transfer = None  # a new request ends the transfer (CiA 301 §7.2.4.3.1)
        if ccs == 2:
            self.upload(data, index, sub)
        elif ccs == 1:
            self.download(data, index, sub)
        else:
            self.refuse(index, sub, 0x05040001, "other")

    def dump(self):
        for (index, sub), entry in sorted(self.entries.items()):
            if entry.access != "wo" and entry.refuse_read is None:
                value = self.values[(index, sub)]
                base.say("DUMP %d %04X %02X %s" % (self.node, index, sub, value.hex().upper()))


class LssSlave:
    """A CiA 305 LSS slave without node-ID, as libnmt's LssSlave answers (lss_slave.cpp)."""

    def __init__(self, bus, address):
        self.bus, self.address = bus, address
        self.configuration = False
        self.selective = 0
        self.position = 0
        self.node_id = 0xFF

    def answer(self, cs, payload=b""):
        data = bytes([cs]) + bytes(payload)
        self.bus.send(can.Message(arbitration_id=0x7E4, is_extended_id=False,
                                  data=data + bytes(8 - len(data))))

    def frame(self, data):
        cs, value = data[0], int.from_bytes(bytes(data[1:5]), "little")
        if cs == 0x04 and data[1] <= 1:
            self.configuration = data[1] == 1
            self.selective = 0
        elif 0x40 <= cs <= 0x43 and not self.configuration:
            step = cs - 0x40
            if (step == self.selective or step == 0) and value == self.address[step]:
                self.selective = step + 1
                if step == 3:
                    self.selective = 0
                    self.configuration = True
                    base.say("LSS SELECTED")
                    self.answer(0x44)
            else:
                self.selective = 0
        elif cs == 0x4C and self.node_id == 0xFF:
            self.answer(0x50)
        elif cs == 0x51 and not self.configuration and self.node_id == 0xFF:
            self.fastscan(data)
        elif cs == 0x11 and self.configuration:
            base.say("LSS CONFIGURE %02X" % data[1])
            self.answer(0x11, [0])
        elif cs == 0x17 and self.configuration:
            base.say("LSS STORE")
            self.answer(0x17, [0])
        elif 0x5A <= cs <= 0x5D and self.configuration:
            self.answer(cs, self.address[cs - 0x5A].to_bytes(4, "little"))
        elif cs == 0x5E and self.configuration:
            self.answer(cs, [self.node_id])

    def fastscan(self, data):
        id_number = int.from_bytes(bytes(data[1:5]), "little")
        bit_check, sub, nxt = data[5], data[6], data[7]
        if bit_check == 0x80:  # reset
            self.position = 0
            self.answer(0x4F)
            return
        if bit_check > 31 or sub > 3 or nxt > 3 or sub != self.position:
            return
        mask = (0xFFFFFFFF << bit_check) & 0xFFFFFFFF
        if (id_number ^ self.address[sub]) & mask:
            return
        self.position = nxt
        self.answer(0x4F)
        if bit_check == 0 and nxt < sub:
            self.position = 0
            self.configuration = True
            base.say("LSS FASTSCAN FOUND")


def main(argv):
    args = list(argv[1:])
    factory, serial = False, 0x5E000000
    while args and args[0].startswith("--"):
        option = args.pop(0)
        if option == "--factory":
            factory = True
        elif option == "--serial":
            serial = int(args.pop(0), 16)
        else:
            print("unknown option " + option, file=sys.stderr)
            return 2
    group, port, timeout = args[0], int(args[1]), float(args[2])
    specs = args[3:]
    with can.Bus(interface="udp_multicast", channel=group, port=port) as bus:
        now = time.monotonic()
        slaves, lss = {}, None
        for spec in specs:
            if spec == "lss":
                lss = LssSlave(bus, (VENDOR, 0x2001, 0x00020001, serial + 0x99))
                continue
            kind, _, node = spec.partition("@")
            node = int(node)
            slaves[node] = ScanSlave(bus, node, KINDS[kind](node, serial + node), factory)
        for slave in slaves.values():
            slave.reset(now)  # power-on
        base.say("READY")
        deadline = now + timeout
        while True:
            now = time.monotonic()
            if now >= deadline:
                base.say("TIMEOUT")
                return 1
            for slave in slaves.values():
                slave.heartbeat(now)
            due = [s.next_heartbeat for s in slaves.values() if s.next_heartbeat is not None]
            msg = bus.recv(max(0.0, min(due + [deadline]) - now))
            if msg is None or msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
                continue
            now = time.monotonic()
            cob = msg.arbitration_id
            if cob == 0x7FF and msg.dlc == 0:
                for node in sorted(slaves):
                    slaves[node].dump()
                base.say("END")
                return 0
            if cob == 0x000 and msg.dlc == 2:
                for slave in slaves.values():
                    if msg.data[1] in (0, slave.node):
                        slave.nmt(msg.data[0], now)
            elif 0x601 <= cob <= 0x67F:
                slave = slaves.get(cob - 0x600)
                if slave is not None:
                    slave.sdo(msg.data, now)
            elif cob == 0x7E5 and msg.dlc == 8 and lss is not None:
                lss.frame(msg.data)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
