#!/usr/bin/python3
"""Hostile command datagrams for pneud, on the LCM group (tests/test_command_security.sh).

  command_datagrams.py capture FILE          wait for one datagram on PNEU_COMMAND, save its bytes
  command_datagrams.py send TTL KIND [FILE]  send one crafted datagram (from the captured template)
  command_datagrams.py flood TTL N           N garbage datagrams on PNEU_COMMAND, back to back

KIND: replay (the template as captured), stale (stamped 10 s ago), future (stamped in 10 s),
nan (set point NaN), out-of-bounds (set point 0.9 m), dirty-origin (control characters in its
origin), truncated, bad-fingerprint, garbage,
oversized (a valid command followed by 2000 bytes), fragment (an LCM "LC03" fragment header),
valid (a fresh set point of 0.15 m).

The LCM short-message form: "LC02" | uint32 sequence | channel NUL | payload; command_t's payload:
int64 fingerprint | int64 utime | int64 seq | int8 kind | double value | int8 origin[32] | int64
session, big-endian. A crafted command keeps the template's origin and session.
"""
import socket
import struct
import sys
import time

GROUP, PORT, CHANNEL = "239.255.76.67", 7667, b"PNEU_COMMAND"
_seq = int(time.time() * 1e6)


def header(channel=CHANNEL, magic=b"LC02"):
    return magic + struct.pack(">I", 1) + channel + b"\0"


def split(datagram):
    at = datagram.index(b"\0", 8) + 1
    return datagram[:at], datagram[at:]


def command(template, utime=None, value=None, kind=1, origin=None):
    global _seq
    head, payload = split(template)
    fingerprint = payload[:8]
    _seq += 1000
    utime = int(time.time() * 1e6) if utime is None else utime
    origin = payload[33:65] if origin is None else origin.ljust(32, b"\0")
    return head + fingerprint + struct.pack(">qqbd", utime, _seq, kind, value) + origin + payload[65:]


def sender(ttl):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
    return s


def main():
    what = sys.argv[1]
    if what == "capture":
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind((GROUP, PORT))
        s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                     socket.inet_aton(GROUP) + socket.inet_aton("0.0.0.0"))
        s.settimeout(10)
        print("ready", flush=True)  # joined: the caller may send now
        while True:
            d, _ = s.recvfrom(65536)
            if d[:4] == b"LC02" and split(d)[0][8:-1] == CHANNEL:
                open(sys.argv[2], "wb").write(d)
                return 0
    ttl = int(sys.argv[2])
    s = sender(ttl)
    if what == "flood":
        garbage = header() + b"\1\2\3"
        for _ in range(int(sys.argv[3])):
            s.sendto(garbage, (GROUP, PORT))
        return 0
    kind = sys.argv[3]
    template = open(sys.argv[4], "rb").read() if len(sys.argv) > 4 else None
    now = int(time.time() * 1e6)
    datagrams = {
        "replay": lambda: template,
        "stale": lambda: command(template, utime=now - 10_000_000, value=0.15),
        "future": lambda: command(template, utime=now + 10_000_000, value=0.15),
        "nan": lambda: command(template, value=float("nan")),
        "out-of-bounds": lambda: command(template, value=0.9),
        "valid": lambda: command(template, value=0.15),
        "dirty-origin": lambda: command(template, value=0.15, origin=b"pneu-dash \x1b[2J\r\n"),
        "truncated": lambda: command(template, value=0.15)[:-4],
        "bad-fingerprint": lambda: (lambda h, p: h + b"\0" * 8 + p[8:])(*split(command(template, value=0.15))),
        "garbage": lambda: header() + b"\xff" * 33,
        "oversized": lambda: command(template, value=0.15) + b"\0" * 2000,
        "fragment": lambda: b"LC03" + struct.pack(">IIIHH", 2, 40000, 0, 0, 3) + CHANNEL + b"\0" + b"\0" * 100,
    }
    s.sendto(datagrams[kind](), (GROUP, PORT))
    return 0


if __name__ == "__main__":
    sys.exit(main())
