"""Many large request bodies at once: what they cost a real ``phongray serve`` on 127.0.0.1.

    python -m bench.bodies [--requests 400] [--workers 2] [--mib 16] [--source DIR] [--env NAME=VALUE ...]

Starts a server of ``--workers`` workers (from the source tree ``--source``, by default this one), then sends
``--requests`` concurrent ``POST /grade`` requests of ``--mib`` MiB each (the scene of tests/scenes/01_three_spheres
and its correct render, padded to the size by a private ancillary PNG chunk), each on its own connection, while a
probe asks ``/healthz`` every 20 ms on a fresh connection.  It prints the status of every request (``reset``: the
connection was closed before an answer came), the growth of the workers' summed resident memory (peak during the
load, and after it), the slowest ``/healthz`` and the seconds the load took, as one JSON line.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from collections import Counter
from pathlib import Path
from typing import Any

from tracer.image import png_chunk

HERE = Path(__file__).resolve().parent.parent
SCENE = HERE / "tests" / "scenes" / "01_three_spheres.json"
PIECE = 256 * 1024  # bytes written at once: the sender's buffers stay small


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _workers(pid: int) -> list[int]:
    """The worker processes of a server (with one worker, uvicorn serves in the server's own process)."""
    with open(f"/proc/{pid}/task/{pid}/children") as f:
        return [int(p) for p in f.read().split()] or [pid]


def _rss_mib(pids: list[int]) -> float:
    total = 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/status") as f:
                total += next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))
        except (OSError, StopIteration):
            pass
    return total / 1024


def padded_png(png: bytes, size: int) -> bytes:
    """``png`` with a private ancillary chunk (``prVt``, which decoders skip) before IEND, ``size`` bytes in all."""
    pad = size - len(png) - 12
    if pad < 0:
        raise ValueError(f"the PNG alone is {len(png)} bytes, more than {size}")
    data = b"\x00" * pad
    return png[:-12] + png_chunk(b"prVt", data) + png[-12:]


def grade_request(host: str, port: int, scene: bytes, png: bytes, total: int) -> bytes:
    """A whole ``POST /grade`` request of ``total`` bytes of body (the image padded to fit)."""
    boundary = "phongraybench"
    head = (
        (f'--{boundary}\r\nContent-Disposition: form-data; name="scene"\r\n\r\n').encode()
        + scene
        + (
            f'\r\n--{boundary}\r\nContent-Disposition: form-data; name="image"; filename="a.png"\r\n'
            f"Content-Type: image/png\r\n\r\n"
        ).encode()
    )
    tail = f"\r\n--{boundary}--\r\n".encode()
    body = head + padded_png(png, total - len(head) - len(tail)) + tail
    return (
        f"POST /grade HTTP/1.1\r\nHost: {host}:{port}\r\nContent-Length: {len(body)}\r\nConnection: close\r\n"
        f"Content-Type: multipart/form-data; boundary={boundary}\r\n\r\n"
    ).encode() + body


async def _one(host: str, port: int, request: memoryview) -> str:
    try:
        reader, writer = await asyncio.open_connection(host, port)
    except OSError:
        return "refused"
    answer = b""
    try:
        try:
            for at in range(0, len(request), PIECE):
                writer.write(request[at : at + PIECE])
                await writer.drain()
        except (ConnectionError, OSError):
            pass  # answered (and closed) before the body was all sent: the answer may still be there to read
        try:
            answer = await asyncio.wait_for(reader.read(), 120)
        except OSError:  # (connection errors and timeouts are OSErrors)
            pass
    finally:
        writer.close()
    if not answer.startswith(b"HTTP/1.1 "):
        return "reset"
    return answer.split(b" ", 2)[1].decode()


async def _load(host: str, port: int, request: bytes, count: int) -> list[str]:
    view = memoryview(request)
    return list(await asyncio.gather(*(_one(host, port, view) for _ in range(count))))


class Probe(threading.Thread):
    """``/healthz`` every 20 ms on a fresh connection; the slowest answer, the failures, and the workers' peak RSS."""

    def __init__(self, url: str, server_pid: int):
        super().__init__(daemon=True)
        self.url, self.server_pid = url, server_pid
        self.worst, self.failures, self.peak_rss = 0.0, 0, 0.0
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            started = time.perf_counter()
            try:
                with urllib.request.urlopen(self.url + "/healthz", timeout=10) as res:
                    res.read()
            except OSError:
                self.failures += 1
            self.worst = max(self.worst, time.perf_counter() - started)
            self.peak_rss = max(self.peak_rss, _rss_mib(_workers(self.server_pid)))
            time.sleep(0.02)


def run(requests: int, workers: int, mib: float, source: Path, env: dict[str, str]) -> dict[str, Any]:
    port = _free_port()
    url = f"http://127.0.0.1:{port}"
    full_env = {**os.environ, **env, "PYTHONPATH": str(source)}
    log = open(f"/tmp/bench-bodies-{port}.log", "w")  # (closed below)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "service.cli",
            "serve",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--workers",
            str(workers),
        ],
        cwd=source,
        env=full_env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    try:
        for _ in range(300):
            try:
                with urllib.request.urlopen(url + "/healthz", timeout=1):
                    pass
                if len(_workers(proc.pid)) >= workers or workers == 1:
                    break
            except OSError:
                pass
            time.sleep(0.1)
        else:
            raise RuntimeError("the server did not start")
        time.sleep(2.0 if workers > 1 else 0.5)  # every worker up and idle
        scene = SCENE.read_bytes()
        render = urllib.request.Request(url + "/render", data=scene, headers={"content-type": "application/json"})
        with urllib.request.urlopen(render, timeout=60) as res:
            png = res.read()
        request = grade_request("127.0.0.1", port, scene, png, int(mib * 1024 * 1024))
        # every worker grades once (the reference cached, the modules loaded) before the baseline is taken
        for status in asyncio.run(_load("127.0.0.1", port, request, 4 * workers)):
            if status != "200":
                raise RuntimeError(f"a single large grade was answered {status}")
        time.sleep(1.0)
        before = _rss_mib(_workers(proc.pid))
        probe = Probe(url, proc.pid)
        probe.start()
        started = time.perf_counter()
        statuses = asyncio.run(_load("127.0.0.1", port, request, requests))
        seconds = time.perf_counter() - started
        time.sleep(1.0)
        probe.done.set()
        probe.join()
        after = _rss_mib(_workers(proc.pid))
        return {
            "requests": requests,
            "workers": workers,
            "body_mib": mib,
            "source": str(source),
            "env": env,
            "statuses": dict(sorted(Counter(statuses).items())),
            "seconds": round(seconds, 2),
            "rss_before_mib": round(before),
            "rss_peak_growth_mib": round(max(probe.peak_rss, after) - before),
            "rss_after_growth_mib": round(after - before),
            "healthz_worst_ms": round(1000 * probe.worst),
            "healthz_failures": probe.failures,
        }
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--requests", type=int, default=400)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--mib", type=float, default=16.0, help="body size of each request, in MiB")
    parser.add_argument("--source", type=Path, default=HERE, help="the source tree to run the server from")
    parser.add_argument("--env", action="append", default=[], metavar="NAME=VALUE", help="a server setting")
    args = parser.parse_args(argv)
    env = dict(item.split("=", 1) for item in args.env)
    print(json.dumps(run(args.requests, args.workers, args.mib, args.source.resolve(), env)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
