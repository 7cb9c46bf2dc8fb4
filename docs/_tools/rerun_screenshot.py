"""Screenshot a rerun recording in rerun's web viewer under headless Chromium, for the docs.

    python docs/_tools/rerun_screenshot.py RECORDING.rrd OUT.png [--timeout 600]

Serves the recording with `rerun --web-viewer`, opens the viewer in headless Chromium (software
rasterizer: no GPU needed) and drives it over the DevTools protocol: it polls the page until the
viewer has drawn its panels (the canvas has stopped changing for a while and the page no longer
says it is loading), however long that takes, then captures the page. A fixed virtual-time budget
does not work: the wasm viewer can take minutes to start on a CPU.
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from pathlib import Path

import websockets

WIDTH, HEIGHT = 1600, 1000
DEBUG_PORT = 9222
GRPC_PORT = 9876          # rerun's default gRPC port, which --web-viewer serves the file on


async def _cdp(ws, counter: list[int], method: str, **params) -> dict:
    counter[0] += 1
    ident = counter[0]
    await ws.send(json.dumps({"id": ident, "method": method, "params": params}))
    while True:
        message = json.loads(await ws.recv())
        if message.get("id") == ident:
            if "error" in message:
                raise RuntimeError(f"{method}: {message['error']}")
            return message.get("result", {})


async def _capture(debug_port: int, url: str, out: Path, timeout: float,
                   args_min_wait: float = 60.0) -> None:
    request = urllib.request.Request(f"http://127.0.0.1:{debug_port}/json/new?{url}", method="PUT")
    with urllib.request.urlopen(request) as resp:
        target = json.loads(resp.read())
    async with websockets.connect(target["webSocketDebuggerUrl"], max_size=2**28) as ws:
        n = [0]
        await _cdp(ws, n, "Page.enable")
        await _cdp(ws, n, "Emulation.setDeviceMetricsOverride", width=WIDTH, height=HEIGHT,
                   deviceScaleFactor=1, mobile=False)
        start, stable_since, last = time.monotonic(), None, None
        while time.monotonic() - start < timeout:
            await asyncio.sleep(5)
            shot = await _cdp(ws, n, "Page.captureScreenshot", format="png")
            text = await _cdp(ws, n, "Runtime.evaluate",
                              expression="document.body ? document.body.innerText : ''")
            loading = "loading" in str(text.get("result", {}).get("value", "")).lower()
            digest = hashlib.sha256(shot["data"].encode()).hexdigest()
            elapsed = time.monotonic() - start
            print(f"{elapsed:6.0f} s  loading={loading}  frame={digest[:8]}", flush=True)
            if digest != last or loading:
                stable_since, last = time.monotonic(), digest
            elif elapsed > args_min_wait and time.monotonic() - stable_since >= 20:
                out.write_bytes(base64.b64decode(shot["data"]))
                print(f"captured after {elapsed:.0f} s: {out}")
                return
        out.write_bytes(base64.b64decode(shot["data"]))
        raise SystemExit(f"the viewer did not settle in {timeout:.0f} s; last frame in {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--port", type=int, default=9090)
    args = parser.parse_args()
    rerun = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("chromium not found: apt-get install chromium")
    server = subprocess.Popen([rerun, "--web-viewer", "--web-viewer-port", str(args.port),
                               str(args.recording)], env={"BROWSER": "true", "PATH": "/usr/bin"},
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              start_new_session=True)
    profile = tempfile.mkdtemp()
    browser = subprocess.Popen([chromium, "--headless=new", "--no-sandbox", "--use-gl=angle",
                                "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                                f"--remote-debugging-port={DEBUG_PORT}",
                                f"--user-data-dir={profile}",
                                f"--window-size={WIDTH},{HEIGHT}", "about:blank"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        url = _viewer_url(server, args.port)
        print("viewer:", url, flush=True)
        _wait_for(f"http://127.0.0.1:{DEBUG_PORT}/json/version", browser)
        asyncio.run(_capture(DEBUG_PORT, url, args.out, args.timeout))
    finally:
        browser.kill()
        os.killpg(server.pid, signal.SIGKILL)   # rerun serves from a child process too
        shutil.rmtree(profile, ignore_errors=True)


def _viewer_url(server: subprocess.Popen, port: int) -> str:
    """The web viewer, pointed at the gRPC proxy that `rerun --web-viewer` serves the file from."""
    _wait_for(f"http://127.0.0.1:{port}", server)
    proxy = urllib.parse.quote(f"rerun+http://127.0.0.1:{GRPC_PORT}/proxy", safe="")
    return f"http://127.0.0.1:{port}/?url={proxy}"


def _wait_for(url: str, process: subprocess.Popen, seconds: float = 60.0) -> None:
    """Until `url` answers; a process that exits first is the error."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            urllib.request.urlopen(url, timeout=2).close()
            return
        except OSError:
            if process.poll() is not None:
                raise SystemExit(f"{process.args[0]} exited with {process.returncode}") from None
            time.sleep(1)
    raise SystemExit(f"{url} did not answer in {seconds:.0f} s")


if __name__ == "__main__":
    main()
