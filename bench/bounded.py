"""Every render bounded: the cases of the ray-tree, cost-model, cancellation and waiting work, against a real
``phongray serve`` on 127.0.0.1, with status, time, peak and final resident memory of the server.

    python -m bench.bounded [--out FILE.md]

Each case gets a fresh single-worker server (so peak memory is that case's), with the settings it names;
"before" is measured after one tiny render, once the renderer's modules are loaded.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

SCENES = Path(__file__).resolve().parent.parent / "tests" / "scenes"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rss(pid: int, field: str = "VmRSS") -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(field + ":")) / 1024


@contextmanager
def _server(**settings: str) -> Iterator[tuple[int, int]]:
    port = _free_port()
    env = {**os.environ, **{f"PHONGRAY_{k.upper()}": v for k, v in settings.items()}}
    proc = subprocess.Popen(
        [sys.executable, "-m", "service.cli", "serve", "--host", "127.0.0.1", "--port", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        for _ in range(200):
            try:
                _request(port, "GET", "/healthz")
                break
            except OSError:
                time.sleep(0.1)
        yield port, proc.pid
    finally:
        proc.terminate()
        proc.wait(timeout=20)


def _request(port: int, method: str, path: str, body: bytes | None = None, timeout: float = 600) -> tuple[int, bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        conn.request(method, path, body=body, headers={"content-type": "application/json"} if body else {})
        res = conn.getresponse()
        return res.status, res.read()
    finally:
        conn.close()


class _Watch:
    """Samples the server's RSS and /healthz latency every 20 ms while a case runs."""

    def __init__(self, port: int, pid: int):
        self.port, self.pid = port, pid
        self.peak, self.healthz_ms, self.stop = 0.0, 0.0, threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self.stop.is_set():
            self.peak = max(self.peak, _rss(self.pid))
            started = time.perf_counter()
            _request(self.port, "GET", "/healthz", timeout=30)
            self.healthz_ms = max(self.healthz_ms, 1000 * (time.perf_counter() - started))
            time.sleep(0.02)

    def __enter__(self) -> _Watch:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()


def nested(depth: int, size: int) -> bytes:
    mats = {"glass": {"reflectance": 0.2, "transmittance": 0.7}, "mirror": {"reflectance": 0.6, "transmittance": 0.3}}
    objs = [
        {"type": "sphere", "material": ["glass", "mirror"][k % 2], "center": [0, 0, 0], "radius": 1.0 - 0.2 * k}
        for k in range(4)
    ]
    return json.dumps(
        {
            "camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]},
            "image": {"width": size, "height": size, "max_depth": depth},
            "materials": mats,
            "objects": objs,
            "lights": [{"type": "point", "color": 1, "position": [2, 2, 2]}],
        }
    ).encode()


def concentric(size: int) -> bytes:
    objs = [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0 + k} for k in range(10_000)]
    return json.dumps(
        {
            "camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]},
            "image": {"width": size, "height": size},
            "materials": {"m": {}},
            "objects": objs,
            "lights": [{"type": "point", "color": 1, "position": [0, 0, 0]}],
        }
    ).encode()


def soft_shadows(size: int) -> bytes:
    data = json.loads((SCENES / "03_soft_shadows.json").read_text())
    data["image"].update(width=size, height=size)
    return json.dumps(data).encode()


def _one(port: int, body: bytes) -> str:
    status, text = _request(port, "POST", "/render", body)
    return str(status) if status == 200 else f"{status} ({json.loads(text)['detail'][:60]}…)"


def _left_after(port: int, pid: int, body: bytes, seconds: float) -> str:
    """Send the request, leave after ``seconds``, and time how long the server's CPU keeps burning."""
    with socket.create_connection(("127.0.0.1", port)) as sock:
        sock.sendall(
            b"POST /render HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
            b"Content-Length: %d\r\n\r\n" % len(body) + body
        )
        time.sleep(seconds)
    left = time.perf_counter()
    ticks = os.sysconf("SC_CLK_TCK")

    def cpu() -> float:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / ticks

    last, quiet_since = cpu(), None
    while time.perf_counter() - left < 30:
        time.sleep(0.25)
        now = cpu()
        if now - last < 0.05:
            quiet_since = quiet_since or time.perf_counter()
            if time.perf_counter() - quiet_since > 1.0:
                return f"client left after {seconds:g} s; CPU stopped {quiet_since - left:.2f} s later"
        else:
            quiet_since = None
        last = now
    return "CPU still busy 30 s after the client left"


def _burst(port: int, body: bytes, count: int) -> str:
    earlier = json.loads(_request(port, "GET", "/healthz")[1])["renders"]
    statuses: list[int] = []
    threads = [
        threading.Thread(target=lambda: statuses.append(_request(port, "POST", "/render", body)[0]))
        for _ in range(count)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    renders = json.loads(_request(port, "GET", "/healthz")[1])["renders"] - earlier
    counts = {s: statuses.count(s) for s in sorted(set(statuses))}
    return f"{', '.join(f'{n}× {s}' for s, n in counts.items())}; renders = {renders}"


CASES: list[tuple[str, dict[str, str], Any]] = [
    ("nested glass/mirror spheres, depth 16, 128² (default limits)", {}, lambda port, pid: _one(port, nested(16, 128))),
    (
        "the same at depth 10, 64², max_cost raised to 1e12",
        {"max_cost": "1e12"},
        lambda port, pid: _one(port, nested(10, 64)),
    ),
    (
        "10,000 concentric spheres, camera inside, 128² (default limits)",
        {},
        lambda port, pid: _one(port, concentric(128)),
    ),
    (
        "the same at 64², max_cost raised to 1e12, client leaves after 2 s",
        {"max_cost": "1e12"},
        lambda port, pid: _left_after(port, pid, concentric(64), 2.0),
    ),
    (
        "100 identical concurrent requests (soft shadows 200²)",
        {"render_threads": "1"},
        lambda port, pid: _burst(port, soft_shadows(200), 100),
    ),
    (
        "a render timing out (0.5 s) with 8 waiters (soft shadows 400²)",
        {"render_threads": "1", "render_timeout": "0.5"},
        lambda port, pid: _burst(port, soft_shadows(400), 8),
    ),
]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.bounded", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", help="also write the Markdown table here")
    args = parser.parse_args(argv)
    lines = [
        "| case | outcome | time (s) | worst /healthz (ms) | RSS before / peak / after (MiB) "
        "| RSS after the same case again (MiB) |",
        "|---|---|---|---|---|---|",
    ]
    print("\n".join(lines), flush=True)
    for name, settings, run in CASES:
        with _server(**settings) as (port, pid):
            warm = json.loads((SCENES / "01_three_spheres.json").read_text())
            warm["image"].update(width=8, height=8)
            _request(port, "POST", "/render", json.dumps(warm).encode())  # modules loaded: the baseline
            before = _rss(pid)
            with _Watch(port, pid) as watch:
                started = time.perf_counter()
                outcome = run(port, pid)
                seconds = time.perf_counter() - started
                time.sleep(1.0)
            peak, after = max(watch.peak, _rss(pid, "VmHWM")), _rss(pid)
            if "timing out" not in name and "concurrent" not in name:  # those would hit the cache the second time
                run(port, pid)
                time.sleep(1.0)
            again = _rss(pid)
            line = (
                f"| {name} | {outcome} | {seconds:.2f} | {watch.healthz_ms:.0f} | "
                f"{before:.0f} / {peak:.0f} / {after:.0f} | {again:.0f} |"
            )
        lines.append(line)
        print(line, flush=True)
    if args.out:
        Path(args.out).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
