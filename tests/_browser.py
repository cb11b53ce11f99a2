"""Headless Chromium for the page tests: a tiny DevTools-protocol client over a pipe.

Chromium is started with ``--remote-debugging-pipe``: it reads protocol commands (JSON, one
per NUL-terminated message) from file descriptor 3 and writes responses and events to file
descriptor 4. No port is opened, no second process (no WebSocket library) is needed, and every
event the page causes is seen: console messages (``Runtime.consoleAPICalled``), uncaught
exceptions (``Runtime.exceptionThrown``), browser log entries (``Log.entryAdded``: failed
loads, blocked requests) and every request the page makes (``Network.requestWillBeSent``).

Shared by the browser tests (``test_report_chromium.py``, ``test_page3d_chromium.py``); the
tests skip with the reason :data:`SKIP_REASON` where no Chromium is installed.
"""

from __future__ import annotations

import base64
import contextlib
import fcntl
import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

#: The browser: Debian's ``chromium`` (CI installs it, see ``.ci/run``), or another Chromium.
CHROMIUM = next((p for p in (shutil.which(n) for n in ("chromium", "chromium-browser",
                                                           "google-chrome")) if p), None)
SKIP_REASON = "headless Chromium not installed (apt-get install chromium)"

#: Flags of every start: headless, offline and quiet (no first-run, sync, component updates or
#: background requests of its own that would be mistaken for the page's), a laptop window.
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--mute-audio", "--no-default-browser-check")

#: URL schemes that are not a network request: the page itself and what it carries inline.
LOCAL_SCHEMES = ("file:", "data:", "blob:", "about:")


#: Run as ``python -c``: fds argv[1], argv[2] onto 3 and 4, then exec argv[3:] (Chromium).
_TRAMPOLINE = ("import os, sys; r, w = int(sys.argv[1]), int(sys.argv[2]); os.dup2(r, 3); "
               "os.dup2(w, 4); os.close(r); os.close(w); os.execv(sys.argv[3], sys.argv[3:])")


def _stderr() -> int | object:
    """Where the browser's own log goes: ``$RFSW_CHROMIUM_LOG`` when set (to debug a start),
    else nowhere."""
    path = os.environ.get("RFSW_CHROMIUM_LOG")
    return open(path, "ab") if path else subprocess.DEVNULL


class BrowserError(RuntimeError):
    """The browser did not answer, or answered a command with an error."""


class Page:
    """One headless Chromium with one tab, driven over the DevTools pipe.

    Use as a context manager: ``with Page(width, height) as page: page.open(path)``.
    ``page.console_errors``, ``page.exceptions`` and ``page.requests`` collect what the page
    did since it was opened.
    """

    def __init__(self, width: int = 1400, height: int = 1000, timeout: float = 60.0) -> None:
        if CHROMIUM is None:
            raise BrowserError(SKIP_REASON)
        self.timeout = timeout
        self._profile = tempfile.TemporaryDirectory(prefix="rfsw-chromium-")
        cmd_r, self._cmd_w = os.pipe()
        self._out_r, out_w = os.pipe()
        # The browser's ends, moved above 9 (so that neither is 3 or 4 itself); a small Python
        # trampoline puts them on fds 3 and 4 and becomes Chromium (no preexec_fn in this
        # process, whose threads a fork would copy mid-flight).
        theirs = [fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10) for fd in (cmd_r, out_w)]
        os.close(cmd_r)
        os.close(out_w)
        r, w = theirs
        argv = [CHROMIUM, *FLAGS, f"--window-size={width},{height}", "--remote-debugging-pipe",
                f"--user-data-dir={self._profile.name}", "about:blank"]
        self._proc = subprocess.Popen(
            [sys.executable, "-c", _TRAMPOLINE, str(r), str(w), *argv],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=_stderr(),
            pass_fds=(r, w))
        for fd in theirs:
            os.close(fd)
        self._next_id = 0
        self._answers: dict[int, dict[str, Any]] = {}
        self._events: queue.Queue[dict[str, Any] | None] = queue.Queue()
        self._lock = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.console_errors: list[str] = []
        self.console: list[str] = []
        self.exceptions: list[str] = []
        self.requests: list[str] = []
        self.loaded = False
        self._session = ""
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        self._session = self.send("Target.attachToTarget",
                                  {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self.send(f"{domain}.enable")
        self.send("Emulation.setDeviceMetricsOverride",
                  {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})

    # -- protocol ----------------------------------------------------------------------------
    def _read(self) -> None:
        buf = b""
        while True:
            try:
                chunk = os.read(self._out_r, 1 << 16)
            except OSError:
                chunk = b""
            if not chunk:
                self._events.put(None)
                with self._lock:
                    self._lock.notify_all()
                return
            buf += chunk
            while b"\0" in buf:
                raw, buf = buf.split(b"\0", 1)
                msg = json.loads(raw)
                if "id" in msg:
                    with self._lock:
                        self._answers[msg["id"]] = msg
                        self._lock.notify_all()
                else:
                    self._note(msg)

    def _note(self, msg: dict[str, Any]) -> None:
        method, p = msg.get("method"), msg.get("params", {})
        if method == "Runtime.consoleAPICalled":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p["args"])
            self.console.append(f"{p['type']}: {text}")
            if p["type"] in ("error", "assert"):
                self.console_errors.append(text)
        elif method == "Runtime.exceptionThrown":
            d = p["exceptionDetails"]
            self.exceptions.append(str(d.get("exception", {}).get("description", d["text"])))
        elif method == "Log.entryAdded" and p["entry"]["level"] == "error":
            self.console_errors.append(f"{p['entry']['source']}: {p['entry']['text']}")
        elif method == "Network.requestWillBeSent":
            self.requests.append(p["request"]["url"])
        elif method == "Page.loadEventFired":
            self.loaded = True

    def send(self, method: str, params: dict[str, Any] | None = None) -> dict[str, Any]:
        """Send one command (to the tab once attached) and wait for its answer."""
        self._next_id += 1
        mid = self._next_id
        msg: dict[str, Any] = {"id": mid, "method": method, "params": params or {}}
        if self._session and not method.startswith("Target."):
            msg["sessionId"] = self._session
        os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        with self._lock:
            while mid not in self._answers:
                left = deadline - time.monotonic()
                if left <= 0 or self._proc.poll() is not None:
                    raise BrowserError(f"no answer to {method} from Chromium")
                self._lock.wait(min(left, 0.5))
            answer = self._answers.pop(mid)
        if "error" in answer:
            raise BrowserError(f"{method}: {answer['error']}")
        return dict(answer.get("result", {}))

    # -- page --------------------------------------------------------------------------------
    def open(self, path: Path) -> None:
        """Load ``path`` (file://) and wait for its ``load`` event."""
        self.loaded = False
        self.send("Page.navigate", {"url": path.resolve().as_uri()})
        self.wait_for(lambda: self.loaded, f"{path.name} to load")

    def wait_for(self, cond: Any, what: str, timeout: float | None = None) -> None:
        deadline = time.monotonic() + (timeout or self.timeout)
        while not cond():
            if time.monotonic() > deadline:
                raise BrowserError(f"timed out waiting for {what}")
            time.sleep(0.05)

    def eval(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page (promises awaited)."""
        res = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                             "awaitPromise": True})
        if "exceptionDetails" in res:
            d = res["exceptionDetails"]
            raise BrowserError(str(d.get("exception", {}).get("description", d["text"])))
        return res["result"].get("value")

    def wait_js(self, expression: str, what: str) -> Any:
        """Wait until a JavaScript expression is truthy; return its value."""
        box: list[Any] = []

        def ready() -> bool:
            box[:] = [self.eval(expression)]
            return bool(box[0])

        self.wait_for(ready, what)
        return box[0]

    def screenshot(self) -> bytes:
        """PNG of the viewport."""
        return base64.b64decode(self.send("Page.captureScreenshot", {"format": "png"})["data"])

    def network_requests(self) -> list[str]:
        """Requests the page made to anything but itself and its inline data."""
        return [u for u in self.requests if not u.startswith(LOCAL_SCHEMES)]

    # -- lifetime ----------------------------------------------------------------------------
    def close(self) -> None:
        try:
            if self._proc.poll() is None:
                with contextlib.suppress(BrowserError):
                    self.send("Browser.close")
                try:
                    self._proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self._proc.kill()
                    self._proc.wait(timeout=10)
        finally:
            os.close(self._cmd_w)
            self._profile.cleanup()

    def __enter__(self) -> Page:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
