"""Load and faults against a real server: bounded overload, disconnects, a killed worker."""

import http.client
import json
import os
import signal
import socket
import statistics
import threading
import time
import urllib.request

import pytest

from helpers import scene_dict
from server import rss_mib, running_server


def cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def healthy(url: str) -> bool:
    try:
        with urllib.request.urlopen(url + "/healthz", timeout=5) as res:
            return json.loads(res.read())["status"] == "ok"
    except OSError:
        return False


def port_of(url: str) -> int:
    return int(url.rsplit(":", 1)[1])


def small_scene(k: int) -> bytes:
    data = scene_dict("01_three_spheres")
    data["image"]["background"] = [0.05 + 1e-6 * k, 0.07, 0.12]
    return json.dumps(data).encode()


def load(url: str, clients: int, seconds: float) -> dict:
    """``clients`` keep-alive clients posting distinct small scenes for ``seconds``."""
    results: list[tuple[int, float, str | None]] = []
    lock = threading.Lock()
    counter = iter(range(10**9))
    deadline = time.perf_counter() + seconds

    def client() -> None:
        conn = http.client.HTTPConnection("127.0.0.1", port_of(url), timeout=30)
        while time.perf_counter() < deadline:
            body = small_scene(next(counter))
            started = time.perf_counter()
            conn.request("POST", "/render", body, {"content-type": "application/json"})
            res = conn.getresponse()
            res.read()
            with lock:
                results.append((res.status, time.perf_counter() - started, res.getheader("retry-after")))
        conn.close()

    started = time.perf_counter()
    threads = [threading.Thread(target=client) for _ in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - started
    ok = sorted(s for code, s, _ in results if code == 200)
    return {
        "results": results,
        "throughput": len(ok) / wall,
        "p50_ms": 1000 * statistics.median(ok),
        "p99_ms": 1000 * ok[int(0.99 * (len(ok) - 1))],
    }


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_server(  # (queue_wait 0: a render finding the one slot taken is refused at once, the overload here)
        tmp_path_factory.mktemp("load"),
        max_concurrent_renders="1",
        render_threads="1",
        max_cost=SLOW_COST,
        queue_wait="0",
    ) as s:
        yield s


def test_overload_gives_only_200_or_503_with_retry_after_and_memory_returns(server):
    url, proc = server
    load(url, clients=2, seconds=1.0)  # warm up: imports, allocator, first renders
    baseline = rss_mib(proc.pid)
    stats = load(url, clients=8, seconds=3.0)
    codes = {code for code, _, _ in stats["results"]}
    assert codes <= {200, 503} and 200 in codes and 503 in codes
    assert all(retry == "1" for code, _, retry in stats["results"] if code == 503)
    big = scene_dict("01_three_spheres")
    big["image"].update(width=1600, height=1200)
    with urllib.request.urlopen(
        urllib.request.Request(
            url + "/render", data=json.dumps(big).encode(), headers={"content-type": "application/json"}
        )
    ) as res:
        assert res.status == 200
    time.sleep(0.5)
    after = rss_mib(proc.pid)
    print(
        f"\nload: {len(stats['results'])} requests, {stats['throughput']:.1f} renders/s, "
        f"p50 {stats['p50_ms']:.1f} ms, "
        f"p99 {stats['p99_ms']:.1f} ms, 503s {sum(c == 503 for c, _, _ in stats['results'])}, "
        f"RSS {baseline:.0f} → {after:.0f} MiB"
    )
    assert after - baseline < 30
    assert healthy(url)


#: the limit max_cost that lets slow_request's scene (an estimated 1.2e8) render rather than be refused
SLOW_COST = "1e9"


def slow_request(url: str) -> socket.socket:
    data = scene_dict("03_soft_shadows")
    data["image"].update(width=640, height=480)
    data["lights"][1]["samples"] = [16, 16]
    body = json.dumps(data).encode()
    sock = socket.create_connection(("127.0.0.1", port_of(url)))
    sock.sendall(
        f"POST /render HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\n\r\n".encode()
        + body
    )
    return sock


def test_a_client_that_disconnects_stops_costing_cpu(server):
    url, proc = server
    with urllib.request.urlopen(url + "/healthz") as res:
        renders_before = json.loads(res.read())["renders"]
    before = cpu_seconds(proc.pid)
    sock = slow_request(url)
    deadline = time.monotonic() + 60  # until the render has cost 0.3 s of CPU (0.8 s on a quiet machine)
    while cpu_seconds(proc.pid) - before < 0.3 and time.monotonic() < deadline:
        time.sleep(0.1)
    busy = cpu_seconds(proc.pid) - before
    sock.close()
    time.sleep(1.5)  # the render stops at its next light or chunk (later on a busy machine: 10 s at most)
    for _ in range(17):
        last = cpu_seconds(proc.pid)
        time.sleep(0.5)
        if cpu_seconds(proc.pid) - last < 0.05:
            break
    settled = cpu_seconds(proc.pid)
    time.sleep(1.5)
    idle = cpu_seconds(proc.pid) - settled
    assert busy >= 0.3, f"the slow render did not run ({busy:.2f} s of CPU)"
    assert idle < 0.3, (busy, idle)
    with urllib.request.urlopen(url + "/healthz") as res:
        assert json.loads(res.read())["renders"] == renders_before
    assert healthy(url)


def children(pid: int) -> list[int]:
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                        out.append(int(entry))
            except OSError:
                continue
    return out


def test_a_worker_killed_mid_render_is_replaced_and_the_service_stays_healthy(tmp_path):
    with running_server(tmp_path, workers=2, render_threads="1", max_cost=SLOW_COST) as (url, proc):
        sock = slow_request(url)
        time.sleep(0.5)
        workers = [p for p in children(proc.pid) if cpu_seconds(p) > 0]
        busiest = max(workers, key=cpu_seconds)
        os.kill(busiest, signal.SIGKILL)
        sock.close()
        for _ in range(100):
            if healthy(url) and len(children(proc.pid)) >= 2 and busiest not in children(proc.pid):
                break
            time.sleep(0.1)
        assert healthy(url)
        assert busiest not in children(proc.pid)
        with urllib.request.urlopen(
            urllib.request.Request(url + "/render", data=small_scene(1), headers={"content-type": "application/json"})
        ) as res:
            assert res.status == 200
