#!/usr/bin/env python3
"""Browse the boards' DNS-SD services with python-zeroconf (Debian's
python3-zeroconf), an mDNS implementation independent of the firmware's.

Usage: browse.py [--seconds S]

Prints one JSON object: for each service type the board announces
(_http._tcp, _rtsp._tcp, _raytracer._tcp), every instance found in S
seconds with its SRV target (the host name), addresses (resolved from the
target's A record), port and TXT. Run by `cargo xtask names` on a host of
the test's own virtual LAN."""

import argparse
import json
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=4.0)
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
    json.dump(out, sys.stdout, indent=1, sort_keys=True)
    print()


if __name__ == "__main__":
    main()
