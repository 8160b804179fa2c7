#!/usr/bin/env python3
"""Browse the boards' DNS-SD services with python-zeroconf (Debian's
python3-zeroconf), an mDNS implementation independent of the firmware's.

Usage: browse.py [--seconds S] [--hosts NAME.local ...]

Prints one JSON object: for each service type the board announces
(_http._tcp, _rtsp._tcp, _raytracer._tcp), every instance found in S
seconds with its SRV target (the host name), addresses (resolved from the
target's A record), port and TXT. With --hosts, also each host name's
addresses as its own one-shot query (RFC 6762 section 5.1: a query to
224.0.0.251:5353 from another port, answered by unicast) finds them: an
answer only a responder that received the multicast query can give, with
no announcement in any cache. Run by `cargo xtask names` on a host of the
test's own virtual LAN."""

import argparse
import json
import socket
import struct
import sys
import time

from zeroconf import ServiceBrowser, ServiceListener, Zeroconf

TYPES = ["_http._tcp.local.", "_rtsp._tcp.local.", "_raytracer._tcp.local."]


class Found(ServiceListener):
    def __init__(self):
        self.names = {t: set() for t in TYPES}

    def add_service(self, zc, type_, name):
        self.names[type_].add(name)

    def update_service(self, zc, type_, name):
        self.names[type_].add(name)

    def remove_service(self, zc, type_, name):
        pass


def one_shot(host, timeout=3.0):
    """The IPv4 addresses a one-shot mDNS query for `host`'s A record
    brings back (empty: no answer in `timeout` seconds)."""
    labels = b"".join(bytes([len(p)]) + p.encode() for p in host.rstrip(".").split(".")) + b"\0"
    query = struct.pack(">HHHHHH", 0x5256, 0, 1, 0, 0, 0) + labels + struct.pack(">HH", 1, 1)
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.settimeout(0.5)
    found = set()
    deadline = time.time() + timeout
    sent = 0.0
    while time.time() < deadline and not found:
        if time.time() - sent > 1.0:
            s.sendto(query, ("224.0.0.251", 5353))
            sent = time.time()
        try:
            data, _ = s.recvfrom(9000)
        except socket.timeout:
            continue
        found |= a_records(data, labels)
    s.close()
    return sorted(found)


def a_records(data, labels):
    """The A records for the name `labels` in a DNS message (answers and
    additionals; names compared uncompressed or by pointer)."""
    def name_at(i):
        out = b""
        while True:
            n = data[i]
            if n >= 0xC0:
                ptr = ((n & 0x3F) << 8) | data[i + 1]
                return out + name_at(ptr)[0], i + 2
            out += bytes([n])
            if n == 0:
                return out, i + 1
            out += data[i + 1:i + 1 + n]
            i += 1 + n

    try:
        _, _, qd, an, ns, ar = struct.unpack(">HHHHHH", data[:12])
        i = 12
        for _ in range(qd):
            _, i = name_at(i)
            i += 4
        found = set()
        for _ in range(an + ns + ar):
            name, i = name_at(i)
            rtype, _, _, rdlen = struct.unpack(">HHIH", data[i:i + 10])
            i += 10
            if rtype == 1 and rdlen == 4 and name.lower() == labels.lower():
                found.add(socket.inet_ntoa(data[i:i + 4]))
            i += rdlen
        return found
    except (IndexError, struct.error):
        return set()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--hosts", nargs="*", default=[])
    args = ap.parse_args()
    zc = Zeroconf(interfaces=["0.0.0.0"])
    found = Found()
    browsers = [ServiceBrowser(zc, t, found) for t in TYPES]
    time.sleep(args.seconds)
    out = {}
    for t in TYPES:
        out[t] = []
        for name in sorted(found.names[t]):
            info = zc.get_service_info(t, name, timeout=3000)
            if info is None:
                out[t].append({"name": name, "resolved": False})
                continue
            txt = {k.decode(): (v.decode() if v is not None else None) for k, v in info.properties.items()}
            out[t].append(
                {
                    "name": name,
                    "resolved": True,
                    "server": info.server,
                    "addresses": info.parsed_addresses(),
                    "port": info.port,
                    "txt": txt,
                }
            )
    for b in browsers:
        b.cancel()
    zc.close()
    if args.hosts:
        out["hosts"] = {h: one_shot(h) for h in args.hosts}
    json.dump(out, sys.stdout, indent=1, sort_keys=True)
    print()


if __name__ == "__main__":
    main()
