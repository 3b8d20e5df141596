"""Issue 44's acceptance for answers, passes and diagnoses: a two-worker ``phongray serve`` on 127.0.0.1 (under
``prlimit --as`` when given a cap) answers a fixed mix of requests of the attacks' kinds, at most ``--clients``
at once, while ``/healthz`` is asked every 0.2 s; prints each kind's outcomes, the slowest ``/healthz``, the
peak of the server's summed proportional (and resident) memory, the worker processes seen (a restart adds
one) and whether any answer was a 5xx other than a 503 the client waited out.

    python -m bench.answers [--requests 100] [--clients 8] [--cap-gib 4] [--side 4096]

The kinds: a noisy image of a 100-point-light 640×480 scene graded (a diagnosis), and the same with a client
that leaves after 3 s; a ``side``² ``?pass=normal&format=npy`` read whole, one never read (looked at once its
answer has begun and send_timeout has passed), and one whose client leaves after 2 s; ``?format=npy`` and
``?light=0`` without a pass (422); small renders and passes.  A 503 is waited out after its ``Retry-After`` (as
the command line's client does) and counted apart; "5xx" counts every other 5xx, and 503s still refused after
10 minutes.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from collections import Counter, defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

SCENES = Path(__file__).parent.parent / "tests" / "scenes"


def many_lights(
    lights: int = 100, width: int = 640, height: int = 480, columns: int = 10, colour: float = 0.01
) -> dict[str, Any]:
    """A floor and a ball under a grid of ``columns`` × ``lights // columns`` dim point lights (and an ambient
    one): the diagnosis's attack scene, whose light terms grow with lights × pixels."""
    grid = [
        {"type": "point", "position": [x * 0.6 - 2.4, 3, z * 0.6 - 1], "color": [colour, colour, colour]}
        for x in range(columns)
        for z in range(lights // columns)
    ]
    return {
        "camera": {"position": [0, 2, 6], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 50},
        "image": {"width": width, "height": height, "samples": 1, "max_depth": 1, "background": [0.1, 0.1, 0.2]},
        "materials": {
            "m": {"diffuse": [0.8, 0.7, 0.6], "specular": [0.3, 0.3, 0.3], "shininess": 20, "ambient": [0.1, 0.1, 0.1]}
        },
        "objects": [
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"},
            {"type": "sphere", "center": [0, 1, 0], "radius": 1, "material": "m"},
        ],
        "lights": [{"type": "ambient", "color": [0.2, 0.2, 0.2]}] + grid,
    }


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Server:
    def __init__(self, cap_gib: float, log: Path, **settings: str):
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        env = {**os.environ, **{f"PHONGRAY_{k.upper()}": v for k, v in settings.items()}}
        command = [
            sys.executable,
            "-m",
            "service.cli",
            "serve",
            "--host",
            "127.0.0.1",
            "--port",
            str(self.port),
            "--workers",
            "2",
        ]
        if cap_gib and shutil.which("prlimit"):
            command = ["prlimit", f"--as={int(cap_gib * 2**30)}", *command]
        self.log = open(log, "w")
        self.proc = subprocess.Popen(command, env=env, stdout=self.log, stderr=subprocess.STDOUT)
        for _ in range(300):
            try:
                with urllib.request.urlopen(self.url + "/healthz", timeout=1):
                    return
            except OSError:
                time.sleep(0.1)
        raise RuntimeError("the server did not start")

    def tree(self) -> list[int]:
        """The server's process and its children."""
        out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(self.proc.pid)], capture_output=True, text=True)
        return [self.proc.pid, *(int(p) for p in out.stdout.split())]

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self.log.close()


def rss(pid: int) -> tuple[int, int]:
    """A process's resident and proportional set sizes (bytes): PSS counts a page shared by the forked workers
    once in all, as a memory cap counts it; RSS counts it in each."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            fields = {line.split(":")[0]: int(line.split()[1]) * 1024 for line in f if line.split()[-1] == "kB"}
        return fields.get("Rss", 0), fields.get("Pss", 0)
    except (OSError, ValueError, IndexError):
        return 0, 0


def raw(url: str, path: str, body: bytes, kind: str) -> socket.socket:
    host, port = url.removeprefix("http://").split(":")
    sock = socket.create_connection((host, int(port)))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.sendall(
        (
            f"POST {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: {kind}\r\nContent-Length: {len(body)}\r\n\r\n"
        ).encode()
        + body
    )
    return sock


def form(scene: bytes, image: bytes) -> tuple[bytes, str]:
    b = "phongrayboundary"
    data = (
        f'--{b}\r\nContent-Disposition: form-data; name="scene"\r\n\r\n'.encode()
        + scene
        + f'\r\n--{b}\r\nContent-Disposition: form-data; name="image"; filename="s.png"\r\n'
        f"Content-Type: image/png\r\n\r\n".encode()
        + image
        + f"\r\n--{b}--\r\n".encode()
    )
    return data, f"multipart/form-data; boundary={b}"


def asked(url: str, path: str, body: bytes, kind: str, waits: Counter) -> tuple[int, int]:
    """Status and bytes read of one request, 503s waited out after their Retry-After (for at most 10 minutes, as
    the command line's client waits)."""
    given_up = time.monotonic() + 600
    while time.monotonic() < given_up:
        req = urllib.request.Request(url + path, body, {"content-type": kind})
        try:
            with urllib.request.urlopen(req, timeout=600) as res:
                size = 0
                while piece := res.read(1 << 20):
                    size += len(piece)
                return res.status, size
        except urllib.error.HTTPError as exc:
            exc.read()
            exc.close()
            if exc.code != 503:
                return exc.code, 0
            waits[path.split("?")[0]] += 1
            time.sleep(float(exc.headers.get("retry-after", "1")))
    return 503, 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.answers", description=__doc__.split("\n\n")[0])
    parser.add_argument("--requests", type=int, default=100)
    parser.add_argument("--clients", type=int, default=8)
    parser.add_argument("--cap-gib", type=float, default=4.0, help="prlimit --as for the server (0: none)")
    parser.add_argument("--side", type=int, default=4096, help="the large passes' width and height")
    parser.add_argument("--render-timeout", default="30")
    parser.add_argument("--send-timeout", default="10")
    args = parser.parse_args(argv)

    crowd = json.dumps(many_lights()).encode()
    noise = io.BytesIO()
    Image.fromarray(np.random.default_rng(1).integers(0, 256, (480, 640, 3), dtype=np.uint8)).save(noise, "PNG")
    graded, graded_kind = form(crowd, noise.getvalue())
    big = json.loads((SCENES / "01_three_spheres.json").read_text())
    big["image"].update(width=args.side, height=args.side)
    big_body = json.dumps(big).encode()
    small = (SCENES / "01_three_spheres.json").read_bytes()
    js = "application/json"
    npy = "/render?pass=normal&format=npy"
    mix = (
        [("diagnosis", "/grade", graded, graded_kind)] * 8
        + [("diagnosis, client leaves", "/grade", graded, graded_kind)] * 6
        + [("big npy pass, read", npy, big_body, js)] * 6
        + [("big npy pass, never read", npy, big_body, js)] * 8
        + [("big npy pass, client leaves", npy, big_body, js)] * 4
        + [("format without pass", "/render?format=npy", small, js)] * 10
        + [("light without pass", "/render?light=0", small, js)] * 10
        + [("small render", "/render?width=160&height=120", small, js)] * 24
        + [("small pass", "/render?pass=depth&width=160&height=120", small, js)] * 24
    )
    random.Random(44).shuffle(mix)
    mix = (mix * (args.requests // len(mix) + 1))[: args.requests]

    logs = Path(tempfile.mkdtemp(prefix="answers-"))
    server = Server(
        args.cap_gib, logs / "server.log", render_timeout=args.render_timeout, send_timeout=args.send_timeout
    )
    done = threading.Event()
    slowest, peak, workers = [0.0], [0, 0], set()
    waits: Counter = Counter()
    outcomes: dict[str, Counter] = defaultdict(Counter)
    started = time.monotonic()

    def watch() -> None:
        while not done.is_set():
            t = time.perf_counter()
            try:
                with urllib.request.urlopen(server.url + "/healthz", timeout=30) as res:
                    workers.add(json.loads(res.read())["worker"])
                slowest[0] = max(slowest[0], time.perf_counter() - t)
            except OSError:
                slowest[0] = float("inf")
            sizes = [rss(p) for p in server.tree()]
            peak[:] = [max(peak[0], sum(r for r, _ in sizes)), max(peak[1], sum(p for _, p in sizes))]
            time.sleep(0.2)

    def one(case: tuple[str, str, bytes, str]) -> None:
        name, path, body, kind = case
        if name.endswith("never read") or name.endswith("client leaves"):
            sock = raw(server.url, path, body, kind)
            if name.endswith("client leaves"):
                time.sleep(3 if path == "/grade" else 2)
                outcomes[name]["left"] += 1
            else:  # never read: once its answer has begun (its first bytes here, looked at without reading),
                # send_timeout and 20 s more; then what had come before the server dropped it, and its end
                begun = time.monotonic() + 600
                while time.monotonic() < begun:
                    try:
                        if sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT):
                            break
                    except BlockingIOError:
                        pass
                    time.sleep(1)
                time.sleep(float(args.send_timeout) + 20)
                sock.settimeout(5)
                got = 0
                try:
                    while piece := sock.recv(1 << 20):
                        got += len(piece)
                    ended = True
                except ConnectionResetError:
                    ended = True
                except OSError:  # (a timeout: the connection is still open)
                    ended = False
                whole = args.side * args.side * 24
                outcomes[name]["dropped by the server" if ended and got < whole else "not dropped"] += 1
            sock.close()
            return
        status, size = asked(server.url, path, body, kind, waits)
        outcomes[name][status] += 1

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        with ThreadPoolExecutor(args.clients) as pool:
            list(pool.map(one, mix))
        time.sleep(1)
    finally:
        done.set()
        watcher.join()
        after = _health(server.url)
        server.stop()
    log = (logs / "server.log").read_text()
    errors = sum(c for counts in outcomes.values() for s, c in counts.items() if isinstance(s, int) and s >= 500)
    print(
        f"{len(mix)} requests, {args.clients} clients at once, 2 workers"
        f"{f' under prlimit --as={args.cap_gib:g} GiB each' if args.cap_gib else ''}, render_timeout "
        f"{args.render_timeout} s, send_timeout {args.send_timeout} s, in {time.monotonic() - started:.0f} s"
    )
    for name in sorted(outcomes):
        print(f"  {name:30s} " + ", ".join(f"{k}: {v}" for k, v in sorted(outcomes[name].items(), key=str)))
    print(f"503 waited out (Retry-After): {dict(waits)}")
    print(
        f"5xx answers: {errors}; 'Traceback' in the server's log: {log.count('Traceback')}; "
        f"MemoryError: {log.count('MemoryError')}"
    )
    print(
        f"worker processes seen: {len(workers)} (2 without a restart); slowest /healthz {slowest[0] * 1000:.0f} ms; "
        f"peak summed PSS {peak[1] / 2**30:.2f} GiB (RSS {peak[0] / 2**30:.2f} GiB, shared pages counted in each "
        f"process); after: answer_bytes {after.get('answer_bytes')}"
    )
    return 0 if errors == 0 and len(workers) == 2 and slowest[0] < 0.5 else 1


def _health(url: str) -> dict[str, Any]:
    try:
        with urllib.request.urlopen(url + "/healthz", timeout=30) as res:
            result: dict[str, Any] = json.loads(res.read())
            return result
    except OSError:
        return {}


if __name__ == "__main__":
    sys.exit(main())
