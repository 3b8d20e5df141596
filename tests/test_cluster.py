"""The same work on a real Dask cluster on 127.0.0.1 (a scheduler and two workers): the same bytes, the same report,
and a batch that survives a worker killed in the middle."""

import json
import os
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

import schemas
import tracer
from helpers import SCENES, scene_dict
from server import free_port, running_server
from service import classgrade, cluster
from service.cli import main

DASK = [sys.executable, "-m", "distributed.cli.dask_worker"]


def _start(args: list[str], log: Path) -> subprocess.Popen:
    with open(log, "w") as out:  # the child keeps its own descriptor
        return subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def _workers(address: str) -> int:
    from distributed import Client

    with Client(address, timeout=10, set_as_default=False) as client:
        return len(client.scheduler_info()["workers"])


@pytest.fixture(scope="module")
def dask(tmp_path_factory):
    """A scheduler and two single-threaded workers (no nanny: a killed worker stays dead); always torn down."""
    logs = tmp_path_factory.mktemp("dask")
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [_start([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
                     str(port), "--dashboard-address", ":0"], logs / "scheduler.log")]
    try:
        for k in range(2):
            procs.append(_start([*DASK, address, "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1",
                                 "--dashboard-address", ":0", "--name", f"w{k}"], logs / f"worker{k}.log"))
        deadline = time.monotonic() + 60
        while True:
            try:
                if _workers(address) == 2:
                    break
            except OSError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("the Dask cluster did not start: " + (logs / "scheduler.log").read_text()[-2000:])
            time.sleep(0.3)
        yield address, procs
    finally:
        for proc in reversed(procs):
            _stop(proc)


def test_a_banded_cluster_render_is_the_local_png_byte_for_byte(dask, tmp_path, monkeypatch):
    address, _ = dask
    monkeypatch.setattr(cluster, "BAND_PIXELS", 1000)  # many bands of a few rows each
    scene = SCENES / "04_whitted.json"
    out = tmp_path / "cluster.png"
    assert main(["render", str(scene), "-o", str(out), "-q", "--cluster", address]) == 0
    local = tracer.encode_png(tracer.render(schemas.load_scene(scene.read_bytes())))
    assert out.read_bytes() == local


def one_task(root: Path, task: str, example: str, width: int, height: int) -> tuple[Path, Path, dict]:
    """A class folder with one task scene (the example at that size) and no students yet."""
    scenes, subs = root / "scenes", root / "subs"
    scenes.mkdir()
    data = scene_dict(example)
    data["image"].update(width=width, height=height)
    (scenes / f"{task}.json").write_text(json.dumps(data))
    return scenes, subs, data


def test_the_class_report_on_the_cluster_equals_the_local_one(dask, tmp_path):
    address, _ = dask
    scenes, subs, data = one_task(tmp_path, "balls", "01_three_spheres", 48, 36)
    right = tracer.encode_png(tracer.render(schemas.validate_scene(json.loads(json.dumps(data)))))
    for student, image in (("a", right), ("b", b"not a png"), ("c", right[:-40]), ("e", right)):
        (subs / student).mkdir(parents=True)
        (subs / student / "balls.png").write_bytes(image)
    (subs / "d").mkdir()
    local = classgrade.grade_class(scenes, subs, tmp_path / "local", jobs=2)
    remote = classgrade.grade_class(scenes, subs, tmp_path / "remote", cluster=address)
    assert remote.rows == local.rows
    assert (tmp_path / "remote" / "report.json").read_bytes() == (tmp_path / "local" / "report.json").read_bytes()


def test_a_batch_survives_a_worker_killed_in_its_middle(dask, tmp_path):
    address, procs = dask
    scenes, subs, data = one_task(tmp_path, "soft", "03_soft_shadows", 96, 72)
    for k in range(16):  # every student has an own scene: 16 renders to share out
        own = json.loads(json.dumps(data))
        own["image"]["background"] = [0.01 * k, 0.02, 0.03]
        (subs / f"s{k:02d}").mkdir(parents=True)
        (subs / f"s{k:02d}" / "soft.json").write_text(json.dumps(own))
        (subs / f"s{k:02d}" / "soft.png").write_bytes(
            tracer.encode_png(tracer.render(schemas.validate_scene(json.loads(json.dumps(own))))))
    done = []
    outcome = {}

    def progress(finished, total):
        done.append(finished)

    thread = threading.Thread(target=lambda: outcome.setdefault(
        "o", classgrade.grade_class(scenes, subs, tmp_path / "report", cluster=address, progress=progress)))
    thread.start()
    deadline = time.monotonic() + 60
    while not any(d >= 2 for d in done) and time.monotonic() < deadline:
        time.sleep(0.05)
    victim = procs[2]
    os.killpg(victim.pid, signal.SIGKILL)  # a worker lost in the middle of the batch
    victim.wait()
    at_kill = max(done)
    thread.join(timeout=180)
    assert not thread.is_alive()
    rows = outcome["o"].rows
    assert len(rows) == 16 and all(r["status"] == "pass" for r in rows), [r["reason"] for r in rows]
    assert at_kill < 12  # the kill came with most of the batch still to do
    assert _workers(address) == 1


def test_the_service_on_the_cluster_gives_the_same_bytes(dask, tmp_path):
    address, _ = dask
    body = (SCENES / "02_all_lights.json").read_bytes()
    local = tracer.encode_png(tracer.render(schemas.load_scene(body)))
    with running_server(tmp_path, cluster=address) as (url, _):
        req = urllib.request.Request(url + "/render", body, {"content-type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as res:
            assert res.read() == local


def test_without_dask_the_cli_says_what_to_install(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if it were not installed
    code = main(["render", str(SCENES / "01_three_spheres.json"), "-o", "-", "--cluster", "tcp://127.0.0.1:1"])
    assert code == 2 and capsys.readouterr().err.strip() == f"phongray: {cluster.INSTALL}"


def test_a_cluster_render_past_the_timeout_is_503_and_its_futures_are_cancelled(dask, tmp_path):
    from distributed import Client

    address, _ = dask
    data = scene_dict("03_soft_shadows")
    data["image"].update(width=400, height=300)
    with running_server(tmp_path, cluster=address, render_timeout="0.5") as (url, _):
        req = urllib.request.Request(url + "/render", json.dumps(data).encode(), {"content-type": "application/json"})
        started = time.monotonic()
        with pytest.raises(urllib.error.HTTPError) as answer:
            urllib.request.urlopen(req, timeout=60)
        answer.value.close()
        assert answer.value.code == 503 and time.monotonic() - started < 5
        with Client(address, timeout=10, set_as_default=False) as client:
            deadline = time.monotonic() + 10
            while any(client.processing().values()) and time.monotonic() < deadline:
                time.sleep(0.1)
            assert not any(client.processing().values())  # nothing of it left running on the workers
