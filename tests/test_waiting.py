"""Requests for a scene already being rendered wait without a thread, and share its outcome; /healthz answers
meanwhile (within a stall's bound here; its budget, 100 ms, is checked by ``python -m bench.budgets``)."""

import http.client
import json
import threading
import time

from helpers import measured, scene_dict
from server import running_server

#: ms: not /healthz's budget (100 ms, the bench's) but 30 times it, a stall that a busy machine does not reach
HEALTHZ_STALL_MS = 3000


def post_render(url: str, body: bytes, timeout: float = 60.0) -> int:
    host, port = url.removeprefix("http://").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=timeout)
    try:
        conn.request("POST", "/render", body=body, headers={"content-type": "application/json"})
        response = conn.getresponse()
        response.read()
        return response.status
    finally:
        conn.close()


def health(url: str) -> dict:
    host, port = url.removeprefix("http://").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=10)
    try:
        conn.request("GET", "/healthz")
        return json.loads(conn.getresponse().read())
    finally:
        conn.close()


def healthz_ms(url: str) -> float:
    started = time.perf_counter()
    health(url)
    return 1000 * (time.perf_counter() - started)


def slow_scene(size: int, samples: int = 1) -> bytes:
    data = scene_dict("03_soft_shadows")
    data["image"].update(width=size, height=size, samples=samples)
    return json.dumps(data).encode()


def burst(url: str, body: bytes, count: int) -> tuple[list[int], list[float]]:
    statuses: list[int] = []
    threads = [threading.Thread(target=lambda: statuses.append(post_render(url, body))) for _ in range(count)]
    for t in threads:
        t.start()
    latencies = []
    while any(t.is_alive() for t in threads):
        latencies.append(healthz_ms(url))
        time.sleep(0.05)
    for t in threads:
        t.join(timeout=60)
    return statuses, latencies


def test_identical_concurrent_requests_render_once_and_all_get_the_image(tmp_path):
    with running_server(tmp_path, render_threads="1") as (url, _):
        statuses, latencies = burst(url, slow_scene(200), 100)
        assert statuses == [200] * 100
        assert latencies, "no /healthz asked while the renders waited"
        measured("100 identical renders at once: worst /healthz (ms)", max(latencies))
        assert max(latencies) < HEALTHZ_STALL_MS, sorted(latencies)[-5:]  # /healthz answered throughout
        assert health(url)["renders"] == 1


def test_a_timed_out_render_answers_all_its_waiters_once(tmp_path):
    with running_server(tmp_path, render_threads="1", render_timeout="0.2") as (url, _):
        statuses, _ = burst(url, slow_scene(400, samples=2), 8)  # about 3 s on one core, 15 times the timeout
        assert statuses == [503] * 8
        assert health(url)["renders"] == 0
