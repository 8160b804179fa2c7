#!/usr/bin/python3
"""Check the board's web page in a real browser (headless Chromium).

    /usr/bin/python3 tests/browser/page_check.py --url http://127.0.0.1:8080 --out target/page-check

1. Opens BASE/?light=3,4,-2, waits for two frames, checks the light of the
   frame on the canvas is exactly (3072, 4096, -2048) raw, and reads the
   canvas back: OUT/held.rgb (480x360 RGB888) and OUT/held.light (x,y,z).
2. Drags on the canvas (60, -25) CSS pixels, waits for a frame of the light
   the page now asks for, reads it back: OUT/drag.rgb, OUT/drag.light.
3. Reads /status twice, some seconds apart: the board's frame counters move,
   one web viewer at least, and the page shows a sent rate above zero
   (OUT/status.json).
4. Saves a screenshot of the page: OUT/page.png.
5. Fails on SEVERE browser console entries (the favicon aside):
   OUT/console.log.
6. Takes every other viewer place with WebSocket handshakes of its own,
   opens the page in a second tab, which must say that every place is
   taken (not that the board is unreachable), then lets the places go:
   the second tab must connect by itself (its retries back off) and draw
   a frame. Its console is not judged (Chromium logs the 503 as SEVERE).

With --play SECONDS, after step 5 the page plays on for that long: every
10-second window must bring new frames, the page must stay connected on
one socket the whole time (no close, no reconnect) and show no error.

With --during "CMD ARGS", CMD runs after step 1 while the page plays (the
hostile clients against the board): the page must draw frames while it
runs; one of them is read back (OUT/during.rgb, OUT/during.light), and
after CMD has ended successfully one more (OUT/after.rgb, OUT/after.light).
Console entries logged while CMD runs go to OUT/console-during.log and are
not judged: the attack makes the board refuse connections on purpose, and
Chromium logs each refusal as SEVERE.

The pixels are not judged here: the Rust side compares the .rgb files with
the bit-exact model. Needs Debian's chromium, chromium-driver and
python3-selenium (Selenium 4).
"""

import argparse
import base64
import socket
import urllib.parse
import json
import math
import os
import subprocess
import sys
import time

import chromium
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By

W, H = 480, 360
FRAME_BYTES = W * H * 3
HELD_RAW = [3072, 4096, -2048]
DRAG = (60, -25)
DRAG_STEPS = [(15, -6), (15, -6), (15, -6), (15, -7)]

# The canvas as RGB bytes (alpha dropped), base64, with the light and the
# count of the frame on it: one script, so all three belong together.
READ_BACK = """
const c = document.getElementById('frame');
const d = c.getContext('2d').getImageData(0, 0, 480, 360).data;
const rgb = new Uint8Array(480 * 360 * 3);
for (let i = 0, j = 0; j < rgb.length; i += 4, j += 3) {
  rgb[j] = d[i]; rgb[j + 1] = d[i + 1]; rgb[j + 2] = d[i + 2];
}
let s = '';
for (let i = 0; i < rgb.length; i += 0x8000) {
  s += String.fromCharCode.apply(null, rgb.subarray(i, i + 0x8000));
}
return {
  b64: btoa(s),
  lightRaw: window.rtPage.lightRaw,
  domRaw: document.getElementById('light').dataset.raw,
  framesDrawn: window.rtPage.framesDrawn,
};
"""

FETCH_STATUS = """
const done = arguments[arguments.length - 1];
fetch('/status', {cache: 'no-store'})
  .then(r => r.ok ? r.json() : Promise.reject(new Error('HTTP ' + r.status)))
  .then(j => done({ok: true, json: j}), e => done({ok: false, error: String(e)}));
"""


class CheckFailed(Exception):
    pass


def step(msg):
    print(f"page check: {msg}", flush=True)


def page_state(driver):
    try:
        return driver.execute_script(
            "return {rtPage: window.rtPage || null,"
            " conn: (document.getElementById('conn') || {}).textContent || null,"
            " notice: (document.getElementById('notice') || {}).textContent || null};"
        )
    except Exception as e:  # noqa: BLE001 - only for the error message
        return f"(state unavailable: {e})"


def wait_for(driver, what, timeout, cond, poll=0.1):
    """Poll cond() until it returns something truthy; fail after timeout."""
    deadline = time.monotonic() + timeout
    while True:
        v = cond()
        if v:
            return v
        if time.monotonic() > deadline:
            raise CheckFailed(f"timed out after {timeout:g} s waiting for {what}; page state: {page_state(driver)}")
        time.sleep(poll)


def rt(driver):
    return driver.execute_script("return window.rtPage || null;")


def read_back(driver, out, name):
    got = driver.execute_script(READ_BACK)
    rgb = base64.b64decode(got["b64"])
    if len(rgb) != FRAME_BYTES:
        raise CheckFailed(f"{name}: read back {len(rgb)} bytes, expected {FRAME_BYTES}")
    raw = got["lightRaw"]
    if not (isinstance(raw, list) and len(raw) == 3):
        raise CheckFailed(f"{name}: no light for the frame on the canvas: {raw!r}")
    if got["domRaw"] != ",".join(str(v) for v in raw):
        raise CheckFailed(f"{name}: #light data-raw {got['domRaw']!r} disagrees with rtPage.lightRaw {raw}")
    with open(os.path.join(out, f"{name}.rgb"), "wb") as f:
        f.write(rgb)
    with open(os.path.join(out, f"{name}.light"), "w") as f:
        f.write(",".join(str(v) for v in raw))
    step(f"saved {name}.rgb ({len(rgb)} bytes) and {name}.light ({','.join(map(str, raw))}), frame {got['framesDrawn']}")
    return raw, rgb


def orbit_raw_after_drag(world, dx, dy):
    """The page's mapping (and rt-client live's), for a sanity check of the drag."""
    x, y, z = world
    y -= 1
    d = math.sqrt(x * x + y * y + z * z)
    az, el = math.atan2(z, x), math.asin(y / d)
    az = (az + dx * 0.01) % (2 * math.pi)
    el = min(math.pi / 2 - 0.05, max(-0.4, el - dy * 0.01))
    d = min(200.0, max(1.5, d))
    h = d * math.cos(el)
    pos = (h * math.cos(az), 1 + d * math.sin(el), h * math.sin(az))
    return [round(v * 1024) for v in pos]


def attack(driver, out, timeout, command):
    """Run the hostile command while the page plays; read frames back."""
    step(f"attack: running {' '.join(command)} while the page plays")
    before = driver.get_log("browser")  # judged with the rest in step 5
    n0 = rt(driver)["framesDrawn"]
    proc = subprocess.Popen(command)
    during = None
    try:
        while proc.poll() is None:
            s = rt(driver)
            if during is None and s["framesDrawn"] >= n0 + 2 and s["lightRaw"] == HELD_RAW:
                during, _ = read_back(driver, out, "during")
            time.sleep(0.5)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    with open(os.path.join(out, "console-during.log"), "w") as f:
        for e in driver.get_log("browser"):
            f.write(f"{e.get('level')} {e.get('source', '')} {e.get('message')}\n")
    if proc.returncode != 0:
        raise CheckFailed(f"the command run during the page failed (exit {proc.returncode})")
    n1 = rt(driver)["framesDrawn"]
    if during is None:
        raise CheckFailed(f"the page drew {n1 - n0} frames while the command ran: it stopped playing")
    if during != HELD_RAW:
        raise CheckFailed(f"during the attack the canvas shows light {during}, expected {HELD_RAW}")
    step(f"the page drew {n1 - n0} frames during the attack")
    wait_for(driver, "a frame after the attack", timeout,
             lambda: (rt(driver) or {}).get("framesDrawn", 0) > n1 and rt(driver)["lightRaw"] == HELD_RAW)
    read_back(driver, out, "after")
    return before


def check(driver, base, out, timeout, during=None, play_s=0):
    # 1. The light from the query, exactly.
    url = base.rstrip("/") + "/?light=3,4,-2"
    step(f"1/6 opening {url}")
    driver.get(url)
    wait_for(driver, "the page script (window.rtPage)", timeout, lambda: rt(driver))
    wait_for(driver, "two frames drawn", timeout, lambda: (rt(driver) or {}).get("framesDrawn", 0) >= 2)
    state = rt(driver)
    if state["lightRaw"] != HELD_RAW:
        raise CheckFailed(f"the frame on the canvas has light {state['lightRaw']}, expected {HELD_RAW} from ?light=3,4,-2")
    if state["targetRaw"] != HELD_RAW:
        raise CheckFailed(f"the page asks for light {state['targetRaw']}, expected {HELD_RAW} until the light is moved")
    if not state["connected"]:
        raise CheckFailed(f"the page says it is not connected: {state}")
    held, _ = read_back(driver, out, "held")
    if held != HELD_RAW:
        raise CheckFailed(f"read back light {held}, expected {HELD_RAW}")
    judged = attack(driver, out, timeout, during) if during else []

    # 2. A drag moves the light; wait for a frame of the new light.
    step(f"2/6 dragging on the canvas by {DRAG} CSS pixels")
    canvas = driver.find_element(By.ID, "frame")
    actions = ActionChains(driver).move_to_element(canvas).click_and_hold()
    for dx, dy in DRAG_STEPS:
        actions = actions.move_by_offset(dx, dy).pause(0.05)
    actions.release().perform()
    state = rt(driver)
    target, n0 = state["targetRaw"], state["framesDrawn"]
    if target == held:
        raise CheckFailed(f"the drag did not move the light: the page still asks for {target}")
    expected = orbit_raw_after_drag([v / 1024 for v in held], *DRAG)
    if any(abs(a - b) > 2 for a, b in zip(target, expected)):
        raise CheckFailed(f"after the drag the page asks for {target}, expected about {expected}")
    step(f"the page now asks for {target} (expected about {expected}); waiting for its frame")

    def settled():
        s = rt(driver)
        return (s["targetRaw"] == target and s["lightRaw"] == target and s["framesDrawn"] > n0) and s

    wait_for(driver, f"a frame of light {target}", timeout, settled)
    drag, _ = read_back(driver, out, "drag")
    if drag != target or drag == held:
        raise CheckFailed(f"read back light {drag}, expected {target}")

    # 3. The board's counters move while the page plays.
    step("3/6 reading /status twice while the page plays")

    def status():
        r = driver.execute_async_script(FETCH_STATUS)
        if not r or not r.get("ok"):
            raise CheckFailed(f"/status failed: {r}")
        return r["json"]

    first = status()
    t0 = time.monotonic()
    time.sleep(2)
    while True:
        second = status()
        moved = (second["frames_sent"] > first["frames_sent"]
                 and second["frames_rendered"] > first["frames_rendered"])
        if moved:
            break
        if time.monotonic() - t0 > timeout:
            raise CheckFailed(f"the board's counters did not move in {timeout:g} s: {first} then {second}")
        time.sleep(1)
    with open(os.path.join(out, "status.json"), "w") as f:
        json.dump([first, second], f, indent=2)
        f.write("\n")
    web = (second.get("viewers") or {}).get("web", 0)
    if web < 1:
        raise CheckFailed(f"/status counts {web} web viewers while the page plays: {second}")
    step(f"frames_sent {first['frames_sent']} -> {second['frames_sent']}, "
         f"frames_rendered {first['frames_rendered']} -> {second['frames_rendered']}, web viewers {web}")

    def shown_rate():
        t = driver.find_element(By.ID, "status-fps-sent").text.strip()
        try:
            return float(t) > 0 and t
        except ValueError:
            return False

    shown = wait_for(driver, "#status-fps-sent to show a rate above 0", timeout, shown_rate, poll=0.2)
    step(f"the page shows {shown} frames/s sent")

    # 4. The screenshot for the README.
    path = os.path.join(out, "page.png")
    step(f"4/6 screenshot {path}")
    if not driver.save_screenshot(path):
        raise CheckFailed("the screenshot failed")

    # 5. The console.
    step("5/6 browser console")
    entries = judged + driver.get_log("browser")
    with open(os.path.join(out, "console.log"), "w") as f:
        for e in entries:
            f.write(f"{e.get('level')} {e.get('source', '')} {e.get('message')}\n")
    severe = [e for e in entries if e.get("level") == "SEVERE" and "favicon" not in e.get("message", "")]
    if severe:
        raise CheckFailed("SEVERE console entries:\n" + "\n".join(f"  {e.get('message')}" for e in severe))
    step(f"{len(entries)} console entries, none severe")
    if play_s:
        play(driver, play_s)
    drawn = rt(driver)["framesDrawn"]
    every_place_taken(driver, base, timeout)
    return drawn


HANDSHAKE = ("GET /ws HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n")


def take_places(base, timeout, most=16):
    """WebSocket handshakes until the board answers 503: the sockets that
    got a place (101), to be closed to give them back."""
    u = urllib.parse.urlsplit(base)
    held = []
    for _ in range(most):
        s = socket.create_connection((u.hostname, u.port or 80), timeout=timeout)
        s.sendall(HANDSHAKE.format(host=u.netloc).encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = s.recv(1024)
            if not chunk:
                break
            head += chunk
        code = head[9:12]
        if code == b"101":
            held.append(s)
            continue
        s.close()
        if code == b"503":
            return held
        raise CheckFailed(f"a viewer handshake was answered {head[:40]!r}, not 101 or 503")
    raise CheckFailed(f"{most} viewer handshakes and no 503")


PLAY_STATE = """
return {drawn: window.rtPage.framesDrawn, connected: window.rtPage.connected,
        error: window.rtPage.lastError, conn: document.getElementById('conn').textContent};
"""


def play(driver, seconds, window=10):
    """The page plays for `seconds` (module docs)."""
    step(f"playing for {seconds:g} s: frames in every {window} s window, one socket, no close")
    start = driver.execute_script(PLAY_STATE)
    last = start
    t0 = time.monotonic()
    windows = 0
    while time.monotonic() - t0 < seconds:
        time.sleep(window)
        now = driver.execute_script(PLAY_STATE)
        windows += 1
        if not now["connected"] or now["error"] != start["error"]:
            raise CheckFailed(f"after {time.monotonic() - t0:.0f} s the page shows {now['conn']!r} "
                              f"(error {now['error']!r}): the viewer was closed")
        if now["drawn"] <= last["drawn"]:
            raise CheckFailed(f"no frame drawn in the {window} s window ending at {time.monotonic() - t0:.0f} s "
                              f"({last['drawn']} frames then and now)")
        last = now
    step(f"played {time.monotonic() - t0:.0f} s: {last['drawn'] - start['drawn']} frames in {windows} windows, "
         f"each with frames, no close")


def every_place_taken(driver, base, timeout):
    """Step 6 (module docs)."""
    step("6/6 taking every viewer place; a second tab must say so, then connect when they are free")
    held = take_places(base, timeout)
    first = driver.current_window_handle
    try:
        driver.switch_to.new_window("tab")
        driver.get(base.rstrip("/") + "/")

        def said():
            t = driver.find_element(By.ID, "conn").text
            return "every viewer place on the board is taken" in t and t

        shown = wait_for(driver, "the second tab to say every place is taken", timeout, said, poll=0.2)
        step(f"the second tab says: {shown!r} ({len(held)} places held here)")
    finally:
        for s in held:
            s.close()
    wait_for(driver, "the second tab to connect by itself and draw a frame", timeout,
             lambda: (rt(driver) or {}).get("framesDrawn", 0) >= 1)
    step(f"the second tab connected and drew a frame: {driver.find_element(By.ID, 'conn').text!r}")
    driver.close()
    driver.switch_to.window(first)


def console_on_failure(driver):
    """After a failure: the browser console's last entries, for the log."""
    try:
        entries = driver.get_log("browser") if driver else []
    except Exception:  # noqa: BLE001 - the browser may be gone
        return
    for e in entries[-10:]:
        print(f"page check: console: {e.get('level')} {e.get('message')}", file=sys.stderr, flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", required=True, help="the page's base URL, e.g. http://127.0.0.1:8080")
    ap.add_argument("--out", required=True, help="directory for the read-back frames, status and screenshot")
    ap.add_argument("--timeout", type=float, default=60, help="seconds to wait for each step (default 60)")
    ap.add_argument("--during", help="a command (words split at spaces) to run while the page plays")
    ap.add_argument("--play", type=float, default=0, help="seconds the page then plays on, watched (default 0)")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    driver = None
    try:
        step("starting headless Chromium")
        driver, profile = chromium.start(args.timeout, log_console=True)
        frames = check(driver, args.url, args.out, args.timeout, args.during.split() if args.during else None,
                       args.play)
        print(f"page check: passed ({frames} frames drawn)", flush=True)
        return 0
    except CheckFailed as e:
        print(f"page check: FAILED: {e}", file=sys.stderr, flush=True)
        console_on_failure(driver)
        return 1
    except Exception as e:  # noqa: BLE001 - a browser or driver failure is a failure too
        # WebDriver errors carry the driver's stack trace in str(e): keep the message.
        msg = (getattr(e, "msg", None) or str(e)).strip()
        print(f"page check: FAILED: {type(e).__name__}: {msg}", file=sys.stderr, flush=True)
        console_on_failure(driver)
        return 1
    finally:
        if driver is not None:
            chromium.stop(driver, profile)


if __name__ == "__main__":
    sys.exit(main())
