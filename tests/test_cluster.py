"""The same work on a real Dask cluster on 127.0.0.1 (a scheduler and two workers): the same bytes, the same report,
and a batch that survives a worker killed in the middle."""

import contextlib
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
from service import classgrade
from service.classgrade import ClassRun
from service.cli import main
from service.render import cluster

from helpers import SCENES, measured, scene_dict
from server import free_port, running_server

DASK = [sys.executable, "-m", "distributed.cli.dask_worker"]


def _start(args: list[str], log: Path) -> subprocess.Popen:
    with open(log, "w") as out:  # the child keeps its own descriptor
        return subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    """End the process and its whole session's group (a worker started under bubblewrap is bubblewrap's child:
    it may outlive bubblewrap's end), asked first, killed after 10 s."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    deadline = time.monotonic() + 10
    while _group_alive(proc) and time.monotonic() < deadline:
        time.sleep(0.05)
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def _group_alive(proc: subprocess.Popen) -> bool:
    proc.poll()  # (reaps the leader once it has ended, so that its group is only what is left of it)
    # (and what of the group this process adopted, as the tests' reaper of orphans, tests/conftest.py: a worker
    # whose bubblewrap ended is this process's child, and unreaped it would count as alive until the kill)
    with contextlib.suppress(ChildProcessError):
        while os.waitpid(-proc.pid, os.WNOHANG)[0] > 0:
            pass
    try:
        os.killpg(proc.pid, 0)
    except ProcessLookupError:
        return False
    return True


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
    procs = [
        _start(
            [
                sys.executable,
                "-m",
                "distributed.cli.dask_scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--dashboard-address",
                "127.0.0.1:0",
            ],
            logs / "scheduler.log",
        )
    ]
    try:
        for k in range(2):
            procs.append(
                _start(
                    [
                        *DASK,
                        address,
                        "--nthreads",
                        "1",
                        "--no-nanny",
                        "--host",
                        "127.0.0.1",
                        "--dashboard-address",
                        "127.0.0.1:0",
                        "--name",
                        f"w{k}",
                    ],
                    logs / f"worker{k}.log",
                )
            )
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
    local = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "local", jobs=2))
    remote = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "remote", cluster=address))
    assert remote.rows == local.rows
    assert (tmp_path / "remote" / "report.json").read_bytes() == (tmp_path / "local" / "report.json").read_bytes()


#: students of the class a worker dies in: enough grades that the kill, a poll after the second, lands mid-batch
STUDENTS = 48


def test_a_batch_survives_a_worker_killed_in_its_middle(dask, tmp_path):
    address, procs = dask
    scenes, subs, data = one_task(tmp_path, "soft", "03_soft_shadows", 96, 72)
    for k in range(STUDENTS):  # every student has an own scene: as many renders to share out
        own = json.loads(json.dumps(data))
        own["image"]["background"] = [0.01 * k, 0.02, 0.03]
        (subs / f"s{k:02d}").mkdir(parents=True)
        (tmp_path / "own" / f"s{k:02d}").mkdir(parents=True)
        (tmp_path / "own" / f"s{k:02d}" / "soft.json").write_text(json.dumps(own))
        (subs / f"s{k:02d}" / "soft.png").write_bytes(
            tracer.encode_png(tracer.render(schemas.validate_scene(json.loads(json.dumps(own)))))
        )
    killed: list[int] = []
    outcome = {}

    def progress(finished, total):
        if finished >= 2 and not killed:  # a worker lost in the middle of the batch: killed from the batch's own
            victim = procs[2]  # thread, as its second grade is kept, so that no busy machine's scheduling can
            os.killpg(victim.pid, signal.SIGKILL)  # let the batch run on to its end before the kill lands
            victim.wait()
            killed.append(finished)

    thread = threading.Thread(
        target=lambda: outcome.setdefault(
            "o",
            classgrade.grade_class(
                ClassRun(scenes, subs, tmp_path / "report", cluster=address, student_scenes=tmp_path / "own"),
                progress=progress,
            ),
        )
    )
    thread.start()
    thread.join(timeout=300)
    assert not thread.is_alive()
    rows = outcome["o"].rows
    assert len(rows) == STUDENTS and all(r["status"] == "pass" for r in rows), [r["reason"] for r in rows]
    assert killed and killed[0] < STUDENTS * 3 // 4  # the kill came with much of the batch still to do
    assert _workers(address) == 1


def test_the_service_on_the_cluster_gives_the_same_bytes(dask, tmp_path):
    address, _ = dask
    body = (SCENES / "02_all_lights.json").read_bytes()
    local = tracer.encode_png(tracer.render(schemas.load_scene(body)))
    with running_server(tmp_path, cluster=address) as (url, _):
        req = urllib.request.Request(url + "/render", body, {"content-type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as res:
            assert res.read() == local


def test_a_students_folder_sent_in_its_task_raises_no_warning_for_the_ta(dask):
    """A program's task carries its student's folder as bytes (up to the folder limit, 100 MB by default):
    sent without Dask's warning of a large graph (the test suite makes every warning an error)."""
    with cluster.client(dask[0]) as held:
        folder = b"\0" * (24 << 20)
        assert held.get_executor().submit(len, folder).result() == 24 << 20


def test_without_dask_the_cli_says_what_to_install(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if it were not installed
    code = main(["render", str(SCENES / "01_three_spheres.json"), "-o", "-", "--cluster", "tcp://127.0.0.1:1"])
    assert code == 2 and capsys.readouterr().err.strip() == f"phongray: {cluster.INSTALL}"


def test_a_cluster_render_past_the_timeout_is_503_and_its_futures_are_cancelled(dask, tmp_path):
    from distributed import Client

    address, _ = dask
    data = scene_dict("03_soft_shadows")
    data["image"].update(width=400, height=400, samples=2)  # about 3 s on one core, 15 times the timeout
    with running_server(tmp_path, cluster=address, render_timeout="0.2") as (url, _):
        req = urllib.request.Request(url + "/render", json.dumps(data).encode(), {"content-type": "application/json"})
        started = time.monotonic()
        with pytest.raises(urllib.error.HTTPError) as answer:
            urllib.request.urlopen(req, timeout=60)
        answer.value.close()
        measured("a cluster render past render_timeout = 0.2 s: 503 after (s)", time.monotonic() - started)
        assert answer.value.code == 503 and time.monotonic() - started < 50  # (not the render's end: see below)
        with Client(address, timeout=10, set_as_default=False) as client:
            deadline = time.monotonic() + 10
            while any(client.processing().values()) and time.monotonic() < deadline:
                time.sleep(0.1)
            assert not any(client.processing().values())  # nothing of it left running on the workers


def test_the_ray_tree_bomb_on_the_cluster_is_stopped_by_its_budget(dask, tmp_path):
    """Each band on a worker is held to the render's budget: the bomb comes back as the service's 422."""
    from test_render import nested_glass_and_mirror

    address, _ = dask
    body = json.dumps(nested_glass_and_mirror(16, 128)).encode()
    with running_server(tmp_path, cluster=address) as (url, _):
        req = urllib.request.Request(url + "/render", body, {"content-type": "application/json"})
        started = time.monotonic()
        with pytest.raises(urllib.error.HTTPError) as answer:
            urllib.request.urlopen(req, timeout=120)
        said = json.loads(answer.value.read())["detail"]
        answer.value.close()
    assert answer.value.code == 422 and "PHONGRAY_MAX_COST" in said, said
    assert time.monotonic() - started < 60  # the foresight stops a band in seconds, far within render_timeout


@pytest.fixture(scope="module")
def idle_scheduler(tmp_path_factory):
    """A Dask scheduler on 127.0.0.1 with no workers at all."""
    logs = tmp_path_factory.mktemp("idle")
    port = free_port()
    proc = _start(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--dashboard-address",
            "127.0.0.1:0",
        ],
        logs / "scheduler.log",
    )
    address = f"tcp://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                _workers(address)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise RuntimeError("the scheduler did not start") from None
                time.sleep(0.3)
        yield address
    finally:
        _stop(proc)


@pytest.mark.parametrize("command", ["render", "grade-class"])
def test_a_cluster_with_no_workers_stops_with_one_line_after_the_wait(idle_scheduler, tmp_path, command):
    scenes, subs, data = one_task(tmp_path, "balls", "01_three_spheres", 16, 12)
    (subs / "a").mkdir(parents=True)
    (subs / "a" / "balls.png").write_bytes(b"")
    args = (
        ["render", str(scenes / "balls.json"), "-o", str(tmp_path / "x.png")]
        if command == "render"
        else ["grade-class", str(scenes), str(subs), "-o", str(tmp_path / "r")]
    )
    started = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "service.cli", *args, "--cluster", idle_scheduler, "--cluster-wait", "1"],
        capture_output=True,
        timeout=120,
    )
    assert done.returncode == 2 and b"Traceback" not in done.stderr, done.stderr
    assert done.stderr.decode() == (
        f"phongray: the Dask scheduler at {idle_scheduler} has no workers (none joined "
        f"within 1 s; start some with 'dask worker {idle_scheduler}', or wait longer "
        f"with --cluster-wait)\n"
    )
    measured(f"{command} on a cluster with no workers, --cluster-wait 1: stopped after (s)", time.monotonic() - started)
    assert not (tmp_path / "r" / "report.json").exists()  # (the run's bound is the subprocess's timeout)


def test_the_service_on_a_cluster_with_no_workers_answers_503_at_once(idle_scheduler, tmp_path):
    with running_server(tmp_path, cluster=idle_scheduler) as (url, _):
        req = urllib.request.Request(
            url + "/render", (SCENES / "01_three_spheres.json").read_bytes(), {"content-type": "application/json"}
        )
        started = time.monotonic()
        with pytest.raises(urllib.error.HTTPError) as answer:
            urllib.request.urlopen(req, timeout=60)
        answer.value.close()
        measured("the service on a cluster with no workers: 503 after (s)", time.monotonic() - started)
        assert answer.value.code == 503  # (not the request's 60 s timeout: answered)


def test_a_class_graded_three_ways_gives_one_report(dask, tmp_path):
    """Locally, through a running service and on the cluster: report.json byte for byte the same."""
    address, _ = dask
    scenes, subs, data = one_task(tmp_path, "balls", "01_three_spheres", 48, 36)
    right = tracer.encode_png(tracer.render(schemas.validate_scene(json.loads(json.dumps(data)))))
    dark = tracer.encode_png(tracer.decode_png(right) // 2)
    own = json.loads(json.dumps(data))
    own["image"]["background"] = [0.2, 0.1, 0.0]
    (tmp_path / "own" / "d").mkdir(parents=True)
    (tmp_path / "own" / "d" / "balls.json").write_text(json.dumps(own))
    for student, name, image in (
        ("a", "balls.png", right),
        ("b", "Balls.PNG", dark),
        ("c", "hw/balls.png", right),
        ("d", "balls.png", right),
        ("e", "balls.jpg", b"\xff\xd8\xff\xe0 a JPEG"),
    ):
        (subs / student / name).parent.mkdir(parents=True, exist_ok=True)
        (subs / student / name).write_bytes(image)
    kw = {"student_scenes": tmp_path / "own"}
    classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "local", jobs=2, **kw))
    classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "cluster", cluster=address, **kw))
    with running_server(tmp_path) as (url, _):
        classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "server", server=url, **kw))
    local = (tmp_path / "local" / "report.json").read_bytes()
    statuses = [r["status"] for r in json.loads(local)]
    assert statuses == ["pass", "fail", "pass", "fail", "invalid"]
    assert (tmp_path / "cluster" / "report.json").read_bytes() == local
    assert (tmp_path / "server" / "report.json").read_bytes() == local


def test_passes_and_diagnoses_on_a_cluster_with_no_workers_answer_503_as_renders_do(idle_scheduler, tmp_path):
    # with PHONGRAY_CLUSTER set, passes and diagnoses ran in the API process, and a pass answered 200 while the
    # cluster had no worker
    body = (SCENES / "01_three_spheres.json").read_bytes()
    with running_server(tmp_path, cluster=idle_scheduler) as (url, _):
        for path in ("/render?pass=diffuse", "/render?pass=normal&format=npy"):
            req = urllib.request.Request(url + path, body, {"content-type": "application/json"})
            with pytest.raises(urllib.error.HTTPError) as answer:
                urllib.request.urlopen(req, timeout=60)
            answer.value.close()
            assert answer.value.code == 503, path


def test_a_pass_and_a_diagnosis_on_the_cluster_are_the_local_ones(dask, tmp_path):
    import io

    from PIL import Image

    from service.diagnosis import diagnose, renders_of
    from service.images.grading import grade
    from service.render import passes

    address, _ = dask
    body = (SCENES / "02_all_lights.json").read_bytes()
    scene = schemas.load_scene(body)
    local = passes.encoded("normal", passes.values(scene, "normal"), "npy")
    reference = tracer.render(scene)
    dim = tracer.render(scene.model_copy(update={"lights": scene.lights[:1]}))
    buf = io.BytesIO()
    Image.fromarray(dim).save(buf, format="PNG")
    verdict = grade(reference, dim, "")
    expected = diagnose(reference, dim, verdict, renders_of(scene)).as_dict()
    with running_server(tmp_path, cluster=address) as (url, proc):
        req = urllib.request.Request(url + "/render?pass=normal&format=npy", body, {"content-type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as res:
            assert res.read() == local
        boundary = "b0undary"
        form = (
            f'--{boundary}\r\nContent-Disposition: form-data; name="scene"\r\n\r\n'.encode()
            + body
            + f'\r\n--{boundary}\r\nContent-Disposition: form-data; name="image"; filename="s.png"\r\n'
            f"Content-Type: image/png\r\n\r\n".encode()
            + buf.getvalue()
            + f"\r\n--{boundary}--\r\n".encode()
        )
        kind = {"content-type": f"multipart/form-data; boundary={boundary}"}
        req = urllib.request.Request(url + "/grade", form, kind)
        with urllib.request.urlopen(req, timeout=300) as res:
            assert json.loads(res.read())["diagnosis"] == json.loads(json.dumps(expected))
