#!/usr/bin/python3
"""Re-serve one stream of the board to any number of players.

The board sends each of its RTSP sessions its own copy of every row (or
one copy to a multicast group on its own link), and takes four sessions
at most. Beyond one network, or for more players, put a relay in
between: this script takes ONE session from the board and serves it
again, shared, to every player that connects (gst-rtsp-server's shared
media: one pipeline, one copy of the board's stream, any number of
clients). Nothing is re-encoded: the rows are depayloaded and payloaded
again as RFC 4175 RGB, byte for byte.

    /usr/bin/python3 tools/rtsp-relay.py 'rtsp://BOARD:8554/orbit?fps=30' --port 8555
    gst-launch-1.0 rtspsrc location=rtsp://RELAY:8555/relay ! rtpvrawdepay ! videoconvert ! autovideosink

Needs Debian's python3-gi and gir1.2-gst-rtsp-server-1.0 (and GStreamer's
good plug-ins); `cargo xtask test` installs them and checks eight players
through it.
"""

import argparse
import signal
import sys

import gi

gi.require_version("Gst", "1.0")
gi.require_version("GstRtspServer", "1.0")
from gi.repository import GLib, Gst, GstRtspServer  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("source", help="the board's stream, rtsp://HOST:8554/...")
    p.add_argument("--address", default="0.0.0.0", help="address to serve on")
    p.add_argument("--port", default="8555", help="RTSP port to serve on")
    p.add_argument("--path", default="/relay", help="the relayed stream's path")
    p.add_argument("--source-transport", default="udp", choices=["udp", "tcp"],
                   help="how the relay itself receives the board's stream")
    args = p.parse_args()

    Gst.init(None)
    server = GstRtspServer.RTSPServer()
    server.set_address(args.address)
    server.set_service(args.port)
    factory = GstRtspServer.RTSPMediaFactory()
    # One rtspsrc session to the board; rtpvrawpay re-packs the rows as
    # RFC 4175 (its own packets, the same pixels).
    factory.set_launch(
        f'( rtspsrc location="{args.source}" protocols={args.source_transport} latency=200 '
        "! rtpvrawdepay ! rtpvrawpay name=pay0 pt=96 )"
    )
    # Shared: every client of the path gets the one pipeline's packets.
    factory.set_shared(True)
    server.get_mount_points().add_factory(args.path, factory)
    if server.attach(None) == 0:
        print(f"rtsp-relay: cannot serve on {args.address}:{args.port}", file=sys.stderr)
        return 1
    print(f"rtsp-relay: rtsp://{args.address}:{args.port}{args.path} relays {args.source}", flush=True)
    loop = GLib.MainLoop()
    signal.signal(signal.SIGTERM, lambda *_: loop.quit())
    signal.signal(signal.SIGINT, lambda *_: loop.quit())
    loop.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
