#!/usr/bin/python3
"""python-can as an independent peer for the nmt tests (UDP multicast bus, trace files).

Frames on the command line use a small text form of our own, parsed here without our C++ code:
  123#DEADBEEF   standard id, data        12345678#00  extended id (more than 3 hex digits)
  123#R / 123#R3 remote frame (dlc 3)     E5#0102       error frame, id 5, data 01 02
Frames are printed one a line as: ID(hex) EXT RTR ERR DLC DATA(hex, '-' when empty), with flags 0/1.

Commands:
  recv GROUP PORT COUNT TIMEOUT_S   join the group, print READY, print COUNT received frames
  send GROUP PORT FRAME...          send the frames to the group, in order
  unpack HEX...                     decode datagrams as python-can does; print their keys, then the frame
  pack FRAME...                     print python-can's datagram for each frame as hex
  readlog FILE                      read a candump log with can.LogReader; print TIMESTAMP and the frame
"""
import sys
import time

import can
import msgpack
from can.interfaces.udp_multicast.utils import pack_message, unpack_message


def parse_frame(text):
    error = text.startswith("E")
    if error:
        text = text[1:]
    ident, _, rest = text.partition("#")
    msg = can.Message(
        arbitration_id=int(ident, 16),
        is_extended_id=len(ident) > 3,
        is_error_frame=error,
        check=False,
    )
    if rest[:1] in ("R", "r"):
        msg.is_remote_frame = True
        msg.dlc = int(rest[1:] or "0")
        msg.data = bytearray()
    else:
        msg.data = bytearray.fromhex(rest)
        msg.dlc = len(msg.data)
    msg._check()
    return msg


def show(msg):
    data = msg.data.hex().upper() if msg.data else "-"
    return "%X %d %d %d %d %s" % (
        msg.arbitration_id,
        msg.is_extended_id,
        msg.is_remote_frame,
        msg.is_error_frame,
        msg.dlc,
        data,
    )


def open_bus(group, port):
    return can.Bus(interface="udp_multicast", channel=group, port=int(port))


def main(argv):
    command = argv[1]
    if command == "recv":
        group, port, count, timeout = argv[2], argv[3], int(argv[4]), float(argv[5])
        with open_bus(group, port) as bus:
            print("READY", flush=True)
            deadline = time.monotonic() + timeout
            for _ in range(count):
                msg = bus.recv(max(0.0, deadline - time.monotonic()))
                if msg is None:
                    print("TIMEOUT", flush=True)
                    return 1
                print(show(msg), flush=True)
        return 0
    if command == "send":
        with open_bus(argv[2], argv[3]) as bus:
            for text in argv[4:]:
                bus.send(parse_frame(text))
        return 0
    if command == "unpack":
        for text in argv[2:]:
            raw = bytes.fromhex(text)
            print(",".join(msgpack.unpackb(raw, raw=False).keys()))
            print(show(unpack_message(raw, check=True)))
        return 0
    if command == "pack":
        for text in argv[2:]:
            print(pack_message(parse_frame(text)).hex())
        return 0
    if command == "readlog":
        for msg in can.LogReader(argv[2]):
            print("%.6f %s" % (msg.timestamp, show(msg)))
        return 0
    print("unknown command " + command, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
