#!/usr/bin/env python3
"""Four pages at once share the board's frames: each gets a fair share.

Opens N headless Chromium browsers (default 4, the board's viewer cap) on
BASE/?light=..., one light each, waits until every page has drawn a frame,
then counts each page's frames over SECONDS (window.rtPage.framesDrawn):
every page must draw at least SHARE of the summed count (default 20%), and
every page some frames. Prints one line a page and a summary; exits 1 on
failure.

The board serves its web viewers from two frame slots, taken in turn
(rt_services::web::server::Turns); a page that never had a turn, or one
that two greedy pages starve, fails here.
"""

import argparse
import sys
import time

import chromium

LIGHTS = ["3,4,-2", "-3,5,1", "0,8,-7", "1.5,2.5,0.75"]

STATE = "return window.rtPage ? {drawn: window.rtPage.framesDrawn, connected: window.rtPage.connected} : null;"


def drawn(driver):
    s = driver.execute_script(STATE)
    return (s or {}).get("drawn", 0) or 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", required=True, help="the page's base URL, e.g. http://127.0.0.1:8080")
    ap.add_argument("--pages", type=int, default=4, help="pages at once (default 4)")
    ap.add_argument("--seconds", type=float, default=30, help="seconds counted (default 30)")
    ap.add_argument("--share", type=float, default=0.2, help="least share of the sum a page draws (default 0.2)")
    ap.add_argument("--timeout", type=float, default=120, help="seconds to wait for every first frame")
    args = ap.parse_args()

    opened = []
    try:
        for k in range(args.pages):
            driver, profile = chromium.start(args.timeout, window="800,600")
            opened.append((driver, profile))
            driver.get(f"{args.url}/?light={LIGHTS[k % len(LIGHTS)]}")
        deadline = time.monotonic() + args.timeout
        while min(drawn(d) for d, _ in opened) < 1:
            if time.monotonic() > deadline:
                got = [drawn(d) for d, _ in opened]
                raise RuntimeError(f"not every page drew a frame within {args.timeout:g} s: {got}")
            time.sleep(0.2)
        start = [drawn(d) for d, _ in opened]
        t0 = time.monotonic()
        time.sleep(args.seconds)
        end = [drawn(d) for d, _ in opened]
        took = time.monotonic() - t0
        counts = [b - a for a, b in zip(start, end)]
        total = sum(counts)
        for k, n in enumerate(counts):
            share = n / total if total else 0
            print(f"pages share: page {k} (light {LIGHTS[k % len(LIGHTS)]}): {n} frames, "
                  f"{n / took:.2f} frames/s, {100 * share:.0f}% of the sum", flush=True)
        if total == 0 or min(counts) < args.share * total:
            raise RuntimeError(f"frames per page {counts}: each must draw at least {100 * args.share:.0f}% "
                               f"of the {total} drawn in {took:.0f} s")
        print(f"pages share: passed: {args.pages} pages drew {counts} frames in {took:.0f} s "
              f"({total / took:.2f} frames/s summed), each at least {100 * args.share:.0f}% of the sum", flush=True)
        return 0
    except Exception as e:  # noqa: BLE001 - a browser or driver failure is a failure too
        msg = (getattr(e, "msg", None) or str(e)).strip()
        print(f"pages share: FAILED: {type(e).__name__}: {msg}", file=sys.stderr, flush=True)
        return 1
    finally:
        for driver, profile in opened:
            chromium.stop(driver, profile)


if __name__ == "__main__":
    sys.exit(main())
