"""Look at an ``rrfrei demo`` page in a real headless browser and save a screenshot.

Usage::

    python docs/check_report.py REPORT_DIR [--screenshot PNG] [--width 1200]

What it does
------------
1. Starts Debian's Chromium (``apt-get install -y chromium``) headless with a throw-away profile
   and the flags that keep it quiet and offline-safe (``--headless --no-sandbox --disable-gpu
   --disable-quic --no-first-run --disable-background-networking --disable-component-update
   --disable-sync --user-data-dir=<temp>``) and ``--remote-debugging-port=0``.
2. Talks to it over the Chrome DevTools Protocol (a websocket; client: the ``websocket-client``
   package from PyPI, ``pip install websocket-client``): enables the Runtime, Log and Page
   domains, opens ``file://REPORT_DIR/index.html`` and waits for the load event.
3. Checks that the page rendered: a title and at least one ``<h2>`` section heading exist, the body
   has text, nothing is wider than the window (wide tables scroll in their box), every ``<img>``
   finished loading with a non-zero natural width (so every embedded base64 PNG decoded), and
   the page made no network request other than its own file and ``data:`` URIs (it must be
   self-contained).
4. Collects console messages (``Runtime.consoleAPICalled``), uncaught exceptions
   (``Runtime.exceptionThrown``) and browser log entries (``Log.entryAdded``, e.g. a failed
   resource load); any message at level error, or any exception, fails the check.
5. Saves a screenshot of the WHOLE page, top to bottom, to ``--screenshot`` (default
   ``REPORT_DIR/screenshot.png``): the window is set to the page width and a tile height
   (``Emulation.setDeviceMetricsOverride``), the page is scrolled tile by tile and each viewport
   captured (``Page.captureScreenshot``), and the tiles are stitched with Pillow at the scroll
   offsets the page reports (one capture of a page taller than the GPU's texture limit, about
   16,000 px, comes back blank or repeated, so it is tiled).  ``--scale`` shrinks the stitched
   image (e.g. 0.5 for the README); the height written always equals the page's.  The page's
   height and the image's are printed, and a mismatch fails the check.

Prints one line per finding and ``report check: OK`` or ``report check: FAILED``; exit status 0
when the page passed, 1 when a check failed, 2 on a usage error (no such folder, no Chromium,
no ``websocket-client``).
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    "--remote-debugging-port=0",
    "--remote-allow-origins=*",
)

PAGE_FACTS_JS = """
(() => {
  const imgs = Array.from(document.images);
  return JSON.stringify({
    title: document.title,
    h1: document.querySelectorAll('h1').length,
    h2: document.querySelectorAll('h2').length,
    tables: document.querySelectorAll('table').length,
    text: (document.body && document.body.innerText || '').length,
    images: imgs.length,
    broken: imgs.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.alt || i.src.slice(0, 40)),
    height: Math.ceil(document.documentElement.scrollHeight),
    width: Math.ceil(document.documentElement.scrollWidth),
    resources: performance.getEntriesByType('resource').map(r => r.name.slice(0, 80)),
  });
})()
"""


def find_chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        path = shutil.which(name)
        if path:
            return path
    raise FileNotFoundError("no Chromium found (install it: apt-get install -y chromium)")


class DevTools:
    """A minimal synchronous CDP session over one page target."""

    def __init__(self, ws_url: str, timeout: float) -> None:
        import websocket  # websocket-client

        self.ws = websocket.create_connection(ws_url, timeout=timeout, suppress_origin=True)
        self.next_id = 0
        self.events: list[dict] = []

    def call(self, method: str, **params) -> dict:
        self.next_id += 1
        my_id = self.next_id
        self.ws.send(json.dumps({"id": my_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == my_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            if "method" in msg:
                self.events.append(msg)

    def wait_event(self, method: str, timeout: float) -> bool:
        end = time.monotonic() + timeout
        if any(e["method"] == method for e in self.events):
            return True
        while time.monotonic() < end:
            msg = json.loads(self.ws.recv())
            if "method" in msg:
                self.events.append(msg)
                if msg["method"] == method:
                    return True
        return False

    def close(self) -> None:
        self.ws.close()


def _devtools_url(profile: Path, proc: subprocess.Popen, timeout: float) -> str:
    """Browser websocket URL from the DevToolsActivePort file Chromium writes in its profile."""
    port_file = profile / "DevToolsActivePort"
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise RuntimeError(f"Chromium exited early with status {proc.returncode}")
        if port_file.exists():
            lines = port_file.read_text().split()
            if len(lines) >= 2:
                return f"ws://127.0.0.1:{lines[0]}{lines[1]}"
        time.sleep(0.1)
    raise RuntimeError("Chromium did not open its DevTools port in time")


def _new_page(browser_ws: str, timeout: float) -> str:
    """Create a blank page target through the browser endpoint; return its websocket URL."""
    import websocket

    ws = websocket.create_connection(browser_ws, timeout=timeout, suppress_origin=True)
    try:
        ws.send(json.dumps({"id": 1, "method": "Target.createTarget", "params": {"url": "about:blank"}}))
        while True:
            msg = json.loads(ws.recv())
            if msg.get("id") == 1:
                target = msg["result"]["targetId"]
                break
    finally:
        ws.close()
    host = browser_ws.split("/devtools/")[0]
    return f"{host}/devtools/page/{target}"


TILE_JS = ("(() => { window.scrollTo(0, %d); return JSON.stringify({y: Math.round(window.scrollY), "
           "h: Math.ceil(document.documentElement.scrollHeight)}); })()")


def full_page(cdp: DevTools, width: int, tile: int):
    """The whole page as one Pillow image: viewport tiles at successive scroll offsets, stitched.

    The window is ``width`` x ``tile`` CSS px at device scale 1; each tile is pasted at the scroll
    offset the page reports (the last tile overlaps the one before when the page does not end on
    a tile boundary).
    """
    import io

    from PIL import Image

    cdp.call("Emulation.setDeviceMetricsOverride", width=width, height=tile, deviceScaleFactor=1,
             mobile=False)
    state = json.loads(cdp.call("Runtime.evaluate", expression=TILE_JS % 0, returnByValue=True)
                       ["result"]["value"])
    height = int(state["h"])
    page = Image.new("RGB", (width, height), "white")
    y = 0
    while True:
        state = json.loads(cdp.call("Runtime.evaluate", expression=TILE_JS % y, returnByValue=True)
                           ["result"]["value"])
        time.sleep(0.05)  # let the compositor paint the scrolled frame
        shot = cdp.call("Page.captureScreenshot", format="png")
        img = Image.open(io.BytesIO(base64.b64decode(shot["data"]))).convert("RGB")
        page.paste(img.crop((0, 0, width, min(img.height, height - state["y"]))), (0, state["y"]))
        if state["y"] + tile >= height or (y > 0 and state["y"] <= y - tile):
            break  # the bottom is in (or the page stopped scrolling)
        y = state["y"] + tile
    return page


def save_screenshot(image, path: Path, scale: float = 1.0) -> list[str]:
    """Write ``image`` (scaled by ``scale``) as PNG; return problems (empty: the whole page is in it)."""
    from PIL import Image

    width, height = image.size
    if scale != 1.0:
        image = image.resize((max(1, round(width * scale)), max(1, round(height * scale))),
                             Image.Resampling.LANCZOS)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, format="PNG", optimize=True)
    print(f"screenshot: {path} ({image.width}x{image.height} px: the whole page of {width}x{height} CSS px"
          + (f" at scale {scale:g})" if scale != 1.0 else ")"))
    problems = []
    if round(height * scale) != image.height:
        problems.append(f"the screenshot is {image.height} px tall, the page {height} px x {scale:g}")
    return problems


def check(report_dir: Path, screenshot: Path, *, width: int = 1200, tile: int = 2000, scale: float = 1.0,
          timeout: float = 60.0) -> list[str]:
    """Render ``report_dir/index.html``; return the list of problems (empty: passed)."""
    page = (report_dir / "index.html").resolve()
    if not page.is_file():
        raise FileNotFoundError(f"no index.html in {report_dir}")
    chromium = find_chromium()
    problems: list[str] = []
    # chromium's helper processes may still write to the profile after the browser exits (seen
    # under load: rmtree found "Default" not empty): a leftover temporary profile is not a failure
    with tempfile.TemporaryDirectory(prefix="rrfrei-chromium-", ignore_cleanup_errors=True) as tmp:
        profile = Path(tmp)
        cmd = [chromium, *FLAGS, f"--user-data-dir={profile}", f"--window-size={width},900",
               "about:blank"]
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            browser_ws = _devtools_url(profile, proc, timeout)
            cdp = DevTools(_new_page(browser_ws, timeout), timeout)
            try:
                cdp.call("Runtime.enable")
                cdp.call("Log.enable")
                cdp.call("Page.enable")
                cdp.call("Page.navigate", url=page.as_uri())
                if not cdp.wait_event("Page.loadEventFired", timeout):
                    problems.append("the page did not finish loading")
                facts = json.loads(cdp.call("Runtime.evaluate", expression=PAGE_FACTS_JS,
                                            returnByValue=True)["result"]["value"])
                print(
                    f"rendered: title {facts['title']!r}, {facts['h2']} sections, {facts['tables']} "
                    f"tables, {facts['images']} images, {facts['width']}x{facts['height']} px"
                )
                if not facts["title"] or facts["h1"] < 1 or facts["h2"] < 1 or facts["text"] < 200:
                    problems.append(f"the page looks empty: {facts}")
                if facts["width"] > width + 20:
                    problems.append(f"the page is wider ({facts['width']} px) than the window ({width} px)")
                if facts["images"] == 0:
                    problems.append("the page has no images")
                for name in facts["broken"]:
                    problems.append(f"image did not load: {name}")
                for url in facts["resources"]:
                    if not url.startswith("data:"):
                        problems.append(f"the page loads an external resource: {url}")
                for ev in cdp.events:
                    m, p = ev["method"], ev.get("params", {})
                    if m == "Runtime.exceptionThrown":
                        det = p["exceptionDetails"]
                        desc = det.get("exception", {}).get("description") or det.get("text")
                        problems.append(f"uncaught exception: {desc}")
                    elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                        text = " ".join(str(a.get("value", a.get("description", ""))) for a in p["args"])
                        problems.append(f"console error: {text}")
                    elif m == "Log.entryAdded" and p["entry"].get("level") == "error":
                        problems.append(f"browser log error: {p['entry'].get('text')}")
                image = full_page(cdp, width, tile)
                problems.extend(save_screenshot(image, screenshot, scale))
            finally:
                cdp.close()
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Render an rrfrei report in headless Chromium, check it and save a screenshot.",
        epilog="Example: rrfrei demo --out report --quick && python docs/check_report.py report",
    )
    parser.add_argument("report_dir", type=Path, help="folder holding index.html")
    parser.add_argument("--screenshot", type=Path, default=None,
                        help="PNG to write (default: REPORT_DIR/screenshot.png, so the tracked "
                             "docs/report.png is only replaced when asked for by name)")
    parser.add_argument("--width", type=int, default=1200)
    parser.add_argument("--tile", type=int, default=2000,
                        help="height [px] of each captured tile (default 2000)")
    parser.add_argument("--scale", type=float, default=1.0,
                        help="shrink the stitched screenshot by this factor (default 1: full size)")
    args = parser.parse_args(argv)
    if args.screenshot is None:
        args.screenshot = args.report_dir / "screenshot.png"
    try:
        import websocket  # noqa: F401
    except ImportError:
        print("check_report: needs websocket-client (pip install websocket-client)", file=sys.stderr)
        return 2
    try:
        problems = check(args.report_dir, args.screenshot, width=args.width, tile=args.tile,
                         scale=args.scale)
    except FileNotFoundError as exc:
        print(f"check_report: {exc}", file=sys.stderr)
        return 2
    for p in problems:
        print(f"problem: {p}")
    print("report check: " + ("OK" if not problems else "FAILED"))
    return 0 if not problems else 1


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
