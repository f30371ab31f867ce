#!/usr/bin/python3
"""An LSS master of CiA 305, written with python-can alone: the independent peer of the LSS
slave of `cfgmgr simulate FILE@255` over the UDP multicast bus (tests/tools/lss_test.cpp).
Nothing here uses our C++ code. The frames are those python-canopen (canopen/lss.py) and
CANopenNode (305/CO_LSS.h) send: COB-ID 7E5h master -> slave, 7E4h slave -> master, 8 data
bytes, unused bytes 0.

Usage: lss_master.py GROUP PORT TIMEOUT_S VENDOR PRODUCT REVISION SERIAL NODE  (numbers hex)

It plays, one step after the other, each waiting for its answer:
  04h 00h                  switch state global: every device to LSS waiting (no answer)
  40h..43h + 1018h sub 1-4 switch state selective; the device answers 44h
  11h NODE                 configure node-ID; the answer is 11h, error code, spec error
  17h                      store configuration; the answer is 17h, error code, spec error
  04h 00h                  back to waiting: the device without node-ID boots, 700h+NODE#00
It prints READY once the bus is open, then each frame it waited for as candump text
(ANSWER 7E4#4400000000000000, BOOT 710#00), flushed, and ends with END (exit 0), or
TIMEOUT after TIMEOUT_S in all (exit 1).
"""
import sys
import time

import can

MASTER, SLAVE = 0x7E5, 0x7E4


def say(text):
    print(text, flush=True)


def candump(msg):
    return "%03X#%s" % (msg.arbitration_id, bytes(msg.data).hex().upper())


def send(bus, cs, value=0, byte1=None):
    data = bytearray(8)
    data[0] = cs
    if byte1 is not None:
        data[1] = byte1
    else:
        data[1:5] = value.to_bytes(4, "little")
    bus.send(can.Message(arbitration_id=MASTER, data=data, is_extended_id=False))


def wait_for(bus, deadline, wanted):
    """The first frame `wanted` accepts, or None at the deadline."""
    while time.monotonic() < deadline:
        msg = bus.recv(0.02)
        if msg is None or msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
            continue
        if wanted(msg):
            return msg
    return None


def main(argv):
    group, port, timeout = argv[1], int(argv[2]), float(argv[3])
    vendor, product, revision, serial, node = (int(a, 16) for a in argv[4:9])
    with can.Bus(interface="udp_multicast", channel=group, port=port) as bus:
        say("READY")
        deadline = time.monotonic() + timeout
        answer = lambda cs: lambda m: m.arbitration_id == SLAVE and m.dlc == 8 and m.data[0] == cs
        send(bus, 0x04, byte1=0x00)
        steps = [
            ([(0x40, vendor), (0x41, product), (0x42, revision), (0x43, serial)], answer(0x44)),
            ([(0x11, None)], answer(0x11)),
            ([(0x17, 0)], answer(0x17)),
        ]
        for frames, wanted in steps:
            for cs, value in frames:
                if value is None:
                    send(bus, cs, byte1=node)
                else:
                    send(bus, cs, value)
            msg = wait_for(bus, deadline, wanted)
            if msg is None:
                say("TIMEOUT")
                return 1
            say("ANSWER " + candump(msg))
        send(bus, 0x04, byte1=0x00)
        boot = wait_for(bus, deadline, lambda m: m.arbitration_id == 0x700 + node and m.dlc == 1)
        if boot is None:
            say("TIMEOUT")
            return 1
        say("BOOT " + candump(boot))
        say("END")
        return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
