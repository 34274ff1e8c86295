"""`fulcrum view` in a real browser: headless Chromium driven over the DevTools protocol.

  live    starts fulcrum-server with tests/cli/data/view_scene.json and `fulcrum view`, loads the
          page, and checks that the canvas shows a body colour where the world has each body
          (screenshot pixels at the page's own view transform, window.fulcrumView.toCanvas) and
          the background where it has none; that the tick shown advances after `run`; that
          dragging a body with the mouse lifts it and the drag joint is gone on release; that a
          body created by an edit while the page is open is drawn.
  replay  records a replay with `fulcrum replay record`, plays it with `fulcrum view --replay`,
          seeks the timeline to a tick and checks that the page shows that tick with the hash
          `fulcrum sim` gives for it; then plays a copy whose hash at one tick was altered and
          checks that the page marks that tick as the first divergent one.

Chromium missing is a failure, not a skip. Timeouts are multiplied by --slow (sanitizer builds).
Usage: view_test.py live|replay --bin DIR --scene FILE --work DIR [--slow K] [--screenshot PNG]
"""
import argparse
import base64
import json
import os
import re
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import urllib.request
import zlib

try:
    import websocket  # Debian's python3-websocket
except ImportError:
    sys.exit("view_test: python3-websocket is not installed (apt-get install python3-websocket; "
             "tools/setup.sh lists it)")

BACKGROUND = (0x1d, 0x20, 0x26)  # view.js colors.background


def fail(message):
    raise AssertionError(message)


def wait_for(what, check, timeout):
    deadline = time.monotonic() + timeout
    while True:
        value = check()
        if value:
            return value
        if time.monotonic() > deadline:
            fail(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(0.1)


class Process:
    """A child process whose stdout is read for a line matching a pattern."""

    def __init__(self, args, log_path, env=None):
        self.args = args
        self.log = open(log_path, "w+")
        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=self.log,
                                     stderr=subprocess.STDOUT, env=env)

    def output(self):
        self.log.flush()
        with open(self.log.name) as f:
            return f.read()

    def wait_line(self, pattern, timeout):
        def found():
            if self.proc.poll() is not None:
                fail(f"{self.args[0]} exited with {self.proc.returncode}:\n{self.output()}")
            m = re.search(pattern, self.output())
            return m
        return wait_for(f"'{pattern}' from {os.path.basename(self.args[0])}", found, timeout)

    def stop(self, expect_zero=True):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                fail(f"{self.args[0]} did not stop within 60 s of SIGTERM")
        if expect_zero and self.proc.returncode != 0:
            fail(f"{self.args[0]} exited with {self.proc.returncode}:\n{self.output()}")


def decode_png(data):
    """RGB(A) pixels of an 8-bit, non-interlaced PNG (what Chromium's screenshots are)."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        fail("screenshot: not a PNG")
    pos, idat, width = 8, b"", 0
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        chunk = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", chunk)
            if depth != 8 or color not in (2, 6) or interlace:
                fail(f"screenshot: unexpected PNG format depth {depth} color {color}")
            channels = 3 if color == 2 else 4
        elif kind == b"IDAT":
            idat += chunk
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    return lambda x, y: tuple(rows[y][x * channels:x * channels + 3])


class Browser:
    """Headless Chromium with one page, driven over the DevTools protocol."""

    def __init__(self, url, work, timeout):
        exe = shutil.which("chromium") or shutil.which("chromium-browser")
        if exe is None:
            fail("chromium is not installed: the viewer's browser test needs it "
                 "(apt-get install chromium; tools/setup.sh lists it)")
        self.profile = tempfile.mkdtemp(prefix="chromium-", dir=work)
        args = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--no-first-run", "--no-default-browser-check", "--disable-extensions",
                "--disable-background-networking", "--mute-audio", "--hide-scrollbars",
                "--force-device-scale-factor=1", "--window-size=1000,640",
                "--remote-allow-origins=*", "--remote-debugging-port=0",
                f"--user-data-dir={self.profile}", url]
        # Chromium's caches and settings go to the profile, not to $HOME (unset or read-only in
        # some CI runners).
        env = dict(os.environ, HOME=self.profile, XDG_CONFIG_HOME=self.profile,
                   XDG_CACHE_HOME=self.profile)
        self.chromium = Process(args, os.path.join(work, "chromium.log"), env)
        port_file = os.path.join(self.profile, "DevToolsActivePort")

        def port():
            if self.chromium.proc.poll() is not None:
                fail(f"chromium exited with {self.chromium.proc.returncode}:\n"
                     f"{self.chromium.output()}")
            return os.path.exists(port_file) and open(port_file).read().split("\n")[0]
        devtools = f"http://127.0.0.1:{wait_for('chromium DevTools port', port, timeout)}"

        def page():
            try:
                targets = json.load(urllib.request.urlopen(devtools + "/json/list", timeout=10))
            except OSError:
                return None
            pages = [t for t in targets if t.get("type") == "page" and t["url"].startswith(url)]
            return pages[0]["webSocketDebuggerUrl"] if pages else None
        self.ws = websocket.create_connection(wait_for("the page in chromium", page, timeout),
                                              timeout=timeout, suppress_origin=True)
        self.next_id = 0

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self.ws.recv())
            if message.get("id") == self.next_id:
                if "error" in message:
                    fail(f"{method}: {message['error']}")
                return message["result"]

    def eval(self, expression):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True,
                      awaitPromise=True)
        if "exceptionDetails" in r:
            fail(f"page: {expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def screenshot(self):
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def mouse(self, kind, x, y):
        self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left",
                  buttons=0 if kind == "mouseReleased" else 1, clickCount=1)

    def close(self):
        try:
            self.call("Browser.close")
        except Exception:  # the browser may be gone already
            pass
        try:
            self.chromium.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.chromium.proc.kill()
            self.chromium.proc.wait()
        shutil.rmtree(self.profile, ignore_errors=True)


def http_json(url, method="GET"):
    request = urllib.request.Request(url, method=method, data=b"" if method == "POST" else None)
    return json.load(urllib.request.urlopen(request, timeout=30))


def origin_inside(shape):
    """Whether the body origin lies inside this shape (body frame), by a margin."""
    if "circle" in shape:
        c = shape["circle"].get("center", {})
        return (c.get("x", 0) ** 2 + c.get("y", 0) ** 2) ** 0.5 < 0.5 * shape["circle"]["radius"]
    if "polygon" in shape:
        v = [(p.get("x", 0), p.get("y", 0)) for p in shape["polygon"]["vertices"]]
        # Counter-clockwise: inside when left of every edge by 0.1 m.
        for (x1, y1), (x2, y2) in zip(v, v[1:] + v[:1]):
            length = ((x2 - x1) ** 2 + (y2 - y1) ** 2) ** 0.5
            if ((x2 - x1) * (0 - y1) - (y2 - y1) * (0 - x1)) / length < 0.1:
                return False
        return True
    if "capsule" in shape:
        a, b = shape["capsule"]["center1"], shape["capsule"]["center2"]
        mid = ((a.get("x", 0) + b.get("x", 0)) / 2, (a.get("y", 0) + b.get("y", 0)) / 2)
        return (mid[0] ** 2 + mid[1] ** 2) ** 0.5 < 0.5 * shape["capsule"]["radius"]
    return False


def check_pixels(browser, description, label):
    """Every body whose origin is inside one of its shapes is drawn in a body colour at its
    origin; a point above the world (in the fitted view's top margin) is background."""
    # What the page shows and where, read in one evaluation, then the pixels. The world is
    # paused and the page's layout has fixed heights; the reading is taken again after the
    # screenshot and must not have changed.
    look = ("(() => { const r = document.getElementById('canvas').getBoundingClientRect(); "
            "return JSON.stringify({rect: [r.left, r.top, r.width, r.height], "
            "bodies: fulcrumView.bodies(), "
            "points: fulcrumView.bodies().map(b => fulcrumView.toCanvas(b.x, b.y)), "
            "view: {ox: fulcrumView.view.ox, oy: fulcrumView.view.oy, "
            "scale: fulcrumView.view.scale}}); })()")
    before = browser.eval(look)
    png = browser.screenshot()
    if browser.eval(look) != before:
        fail(f"{label}: the page changed while its screenshot was taken")
    before = json.loads(before)
    rect, bodies, points, view = (before[k] for k in ("rect", "bodies", "points", "view"))
    with open(os.path.join(os.path.dirname(browser.profile), "last_screenshot.png"), "wb") as f:
        f.write(png)  # kept for a failure
    pixel = decode_png(png)
    shapes = {(b["handle"]["index"], b["handle"]["generation"]): b["body"]["shapes"]
              for b in description["bodies"]}
    checked = 0
    for body, (px, py) in zip(bodies, points):
        if not any(origin_inside(s) for s in shapes.get((body["index"], body["gen"]), [])):
            continue
        x, y = int(rect[0] + px), int(rect[1] + py)
        if not (0 <= px < rect[2] and 0 <= py < rect[3]):
            fail(f"{label}: body {body['index']} at ({body['x']:.2f}, {body['y']:.2f}) m is "
                 f"outside the canvas at ({px:.0f}, {py:.0f}) px")
        got = pixel(x, y)
        if max(abs(g - b) for g, b in zip(got, BACKGROUND)) < 40:
            fail(f"{label}: body {body['index']} ({body['type']}) at ({body['x']:.3f}, "
                 f"{body['y']:.3f}) m, canvas ({px:.1f}, {py:.1f}) px, shows background "
                 f"{got}")
        checked += 1
    if checked < 10:
        fail(f"{label}: only {checked} bodies had their origin inside a shape")
    # The fitted view leaves a margin above the highest shape: its middle is background. The
    # vertical axis line is avoided by going 40 px to the side of x = 0.
    top = max(b["y"] for b in bodies)
    empty = (int(rect[0] + view["ox"] + 40), int(rect[1] + min(view["oy"] - (top + 3) *
                                                                  view["scale"], 12)))
    if empty[1] < rect[1]:
        empty = (empty[0], int(rect[1] + 4))
    got = pixel(*empty)
    if max(abs(g - b) for g, b in zip(got, BACKGROUND)) > 3:
        fail(f"{label}: the empty point {empty} px shows {got}, not the background {BACKGROUND}")
    print(f"{label}: {checked} bodies drawn in a body colour at their origins; the empty point "
          f"{empty} px is background")


def shown_tick(browser):
    text = browser.eval("document.getElementById('tick').textContent")
    return int(text) if text.isdigit() else None


def run_live(a, bins, work, slow):
    server = Process([os.path.join(bins, "fulcrum-server"), "--listen", "127.0.0.1:0",
                      "--log", "off"], os.path.join(work, "server.log"))
    view = browser = None
    try:
        address = server.wait_line(r"listening on (\S+)", 30 * slow).group(1)
        subprocess.run([os.path.join(bins, "fulcrum"), "create", "--server", address,
                        "--scene", a.scene], check=True, stdin=subprocess.DEVNULL,
                       stdout=subprocess.DEVNULL, timeout=60 * slow)
        view = Process([os.path.join(bins, "fulcrum"), "view", "--server", address, "--listen",
                        "127.0.0.1:0", "--world", "1"], os.path.join(work, "view.log"))
        url = view.wait_line(r"serving (http://\S+)", 30 * slow).group(1)
        base = url.split("?")[0]
        browser = Browser(url, work, 60 * slow)
        wait_for("the page to draw the world", lambda: browser.eval(
            "window.fulcrumView !== undefined && fulcrumView.ready()"), 60 * slow)
        description = http_json(base + "api/describe?world=1")
        check_pixels(browser, description, "live, tick 0")

        # Run: the tick shown advances.
        start = shown_tick(browser)
        browser.eval("document.getElementById('run').click()")
        wait_for("the tick shown to advance by 30", lambda: (shown_tick(browser) or 0) >=
                 start + 30, 60 * slow)
        print(f"live: tick shown went from {start} to {shown_tick(browser)} while running")

        # Drag the ball (scene body 27) up 3 m while the world runs; release.
        ball = [b for b in browser.eval("fulcrumView.bodies()") if b["index"] == 27][0]
        x, y = browser.eval(f"fulcrumView.toCanvas({ball['x']}, {ball['y']})")
        left, top = browser.eval("(() => { const r = document.getElementById('canvas')"
                                 ".getBoundingClientRect(); return [r.left, r.top]; })()")
        lift = 3 * browser.eval("fulcrumView.view.scale")
        browser.mouse("mousePressed", left + x, top + y)
        wait_for("the drag joint", lambda: any(j["type"] == "JOINT_TYPE_TARGET" for j in http_json(
            base + "api/describe?world=1").get("joints", [])), 30 * slow)
        for k in range(1, 11):
            browser.mouse("mouseMoved", left + x, top + y - lift * k / 10)
            time.sleep(0.05)
        wait_for("the ball to rise 2 m", lambda: [b for b in browser.eval("fulcrumView.bodies()")
                                                  if b["index"] == 27][0]["y"] > ball["y"] + 2,
                 60 * slow)
        browser.mouse("mouseReleased", left + x, top + y - lift)
        wait_for("the drag joint to be destroyed", lambda: not any(
            j["type"] == "JOINT_TYPE_TARGET" for j in http_json(
                base + "api/describe?world=1").get("joints", [])), 30 * slow)
        print("live: dragging the ball lifted it; the drag joint is gone after release")

        # Pause, let the last frames arrive, and look again.
        browser.eval("document.getElementById('pause').click()")
        paused = http_json(base + "api/pause?world=1", method="POST")["tick"]
        wait_for(f"the page to show the paused tick {paused}",
                 lambda: shown_tick(browser) == paused, 30 * slow)

        # A body made by an edit while the page is open: the page describes the world again
        # and draws it (check_pixels below looks at every body).
        edits = os.path.join(work, "edits.json")
        with open(edits, "w") as f:
            json.dump({"edits": [{"createBody": {
                "type": "BODY_TYPE_KINEMATIC", "position": {"x": -3, "y": 7},
                "shapes": [{"circle": {"radius": 0.7}}]}}]}, f)
        subprocess.run([os.path.join(bins, "fulcrum"), "edit", "1", "--server", address,
                        "--file", edits], check=True, stdin=subprocess.DEVNULL,
                       stdout=subprocess.DEVNULL, timeout=60 * slow)
        wait_for("the page to draw the new body", lambda: browser.eval(
            "fulcrumView.ready() && fulcrumView.bodies().some(b => "
            "b.type === 'BODY_TYPE_KINEMATIC')"), 30 * slow)
        time.sleep(0.3)  # one more animation frame
        check_pixels(browser, http_json(base + "api/describe?world=1"), f"live, tick {paused}")
        if a.screenshot:
            with open(a.screenshot, "wb") as f:
                f.write(browser.screenshot())
    finally:
        if browser:
            browser.close()
        if view:
            view.stop()
        server.stop()


def alter_hash(path, out, tick):
    """Copies a replay file, flipping one bit of the recorded state hash of `tick` (and fixing
    that record's checksum, so that the file reads and only the hash is wrong)."""
    data = open(path, "rb").read()
    pos, result = 0, bytearray()

    def varint(buf, p):
        value, shift = 0, 0
        while True:
            b = buf[p]
            value |= (b & 0x7F) << shift
            p += 1
            shift += 7
            if b < 0x80:
                return value, p
    done = False
    while pos < len(data):
        length, body_at = varint(data, pos)
        body = bytearray(data[body_at:body_at + length])
        # ReplayRecord.tick (field 2) -> ReplayTick{tick = 1 (varint), ..., state_hash = 3
        # (fixed64)}.
        if body and body[0] == 0x12:
            inner_len, p = varint(body, 1)
            end = p + inner_len
            record_tick = None
            while p < end:
                key, p = varint(body, p)
                field, wire = key >> 3, key & 7
                if wire == 0:
                    value, p = varint(body, p)
                    if field == 1:
                        record_tick = value
                elif wire == 1:
                    if field == 3 and record_tick == tick:
                        body[p] ^= 1
                        done = True
                    p += 8
                elif wire == 2:
                    n, p = varint(body, p)
                    p += n
                else:
                    p += 4
        checksum = 0xCBF29CE484222325
        for b in body:
            checksum = ((checksum ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
        result += data[pos:body_at] + body + checksum.to_bytes(8, "little")
        pos = body_at + length + 8
    if not done:
        fail(f"alter_hash: no record of tick {tick} in {path}")
    open(out, "wb").write(bytes(result))


def run_replay(a, bins, work, slow):
    fulcrum = os.path.join(bins, "fulcrum")
    replay = os.path.join(work, "view.replay")
    subprocess.run([fulcrum, "replay", "record", "--scene", a.scene, "--ticks", "150", "--out",
                    replay, "--keyframes", "50"], check=True, stdin=subprocess.DEVNULL,
                   stdout=subprocess.DEVNULL, timeout=120 * slow)
    seek_to = 97

    def sim_hash(ticks):
        out = subprocess.run([fulcrum, "sim", "--scene", a.scene, "--ticks", str(ticks), "--json"],
                             check=True, capture_output=True, text=True, timeout=120 * slow)
        return json.loads(out.stdout)["stateHash"]

    def open_view(path, log):
        view = Process([fulcrum, "view", "--replay", path, "--listen", "127.0.0.1:0"],
                       os.path.join(work, log))
        url = view.wait_line(r"serving (http://\S+)", 60 * slow).group(1)
        browser = Browser(url, work, 60 * slow)
        wait_for("the page to draw the replay", lambda: browser.eval(
            "window.fulcrumView !== undefined && fulcrumView.ready()"), 60 * slow)
        return view, browser, url

    def seek(browser, tick):
        # As a person would: move the timeline's slider.
        browser.eval(f"(() => {{ const s = document.getElementById('seek'); s.value = {tick}; "
                     "s.dispatchEvent(new Event('input')); })()")
        wait_for(f"the page to show tick {tick}", lambda: shown_tick(browser) == tick and
                 browser.eval("fulcrumView.ready()"), 60 * slow)

    view, browser, url = open_view(replay, "view.log")
    try:
        verdict = browser.eval("document.getElementById('verdict').textContent")
        if not verdict.startswith("verified: 150 ticks match"):
            fail(f"replay: the page says '{verdict}' of a replay that verifies")
        for tick in (seek_to, 20, 150):
            seek(browser, tick)
            shown = browser.eval("document.getElementById('hash').textContent")
            want = sim_hash(tick)
            if shown != want:
                fail(f"replay: tick {tick} shows hash '{shown}', fulcrum sim gives {want}")
            print(f"replay: seeking to tick {tick} shows tick {tick}, hash {shown} "
                  "(as fulcrum sim)")
        seek(browser, seek_to)
        check_pixels(browser, http_json(url + "api/describe"), f"replay, tick {seek_to}")
    finally:
        browser.close()
        view.stop()

    altered = os.path.join(work, "altered.replay")
    alter_hash(replay, altered, 60)
    view, browser, url = open_view(altered, "view_altered.log")
    try:
        verdict = browser.eval("document.getElementById('verdict').textContent")
        mark = browser.eval("getComputedStyle(document.getElementById('divergence')).display")
        if verdict != "diverges at tick 60" or mark != "block":
            fail(f"replay: altered at tick 60, the page says '{verdict}' (marker {mark})")
        seek(browser, 60)
        shown = browser.eval("document.getElementById('hash').textContent")
        if "(file: " not in shown:
            fail(f"replay: tick 60 of the altered file shows '{shown}' without the file's hash")
        print(f"replay: the altered file is marked as diverging at tick 60 ('{shown}')")
    finally:
        browser.close()
        view.stop()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("mode", choices=["live", "replay"])
    p.add_argument("--bin", required=True)
    p.add_argument("--scene", required=True)
    p.add_argument("--work", required=True)
    p.add_argument("--slow", type=float, default=1.0)
    p.add_argument("--screenshot")
    a = p.parse_args()
    work = os.path.join(a.work, f"view_test_{a.mode}")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    started = time.monotonic()
    try:
        (run_live if a.mode == "live" else run_replay)(a, a.bin, work, a.slow)
    except AssertionError as e:
        print(f"view_test {a.mode}: FAILED: {e}")
        for log in sorted(os.listdir(work)):
            if log.endswith(".log"):
                text = open(os.path.join(work, log)).read()
                print(f"--- {log} (last 30 lines)\n" + "\n".join(text.splitlines()[-30:]))
        return 1
    print(f"view_test {a.mode}: OK in {time.monotonic() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
