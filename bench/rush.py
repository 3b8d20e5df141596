"""A deadline rush on ``POST /grade``: a class of students, each with their own copy of a homework scene, all
grading at once against a ``phongray serve`` of two workers on 127.0.0.1; each client tries again after a 503's
``Retry-After``, a number of times.  A verdict must not depend on the load: every student is answered, the
honest ones pass and the mistaken ones fail.

    python -m bench.rush [--students 40] [--workers 2] [--tries 20] [--scene examples/09_cornell_homework.json]
                         [--size WxH] [--same-scene] [--seed 1] [--set NAME=VALUE ...]

The class: 70 % exact images, 15 % an honest tracer's 1e-3 ray offset along the normal (an accepted variant,
:mod:`tracer.scene.variants`), 15 % no shadow rays, in a shuffled order.  Each student's copy differs from the others
by a background a millionth brighter per student (a distinct scene to the server, as a class's copies are),
unless ``--same-scene``; each image is rendered from the student's own copy.  ``--set queue_wait=5`` passes
``PHONGRAY_QUEUE_WAIT=5`` to the server.  Prints each kind's outcomes (right verdicts, wrong, never answered,
tries, 503s waited out and their Retry-After) and exits 1 unless every student got the right verdict.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

HOMEWORK = Path(__file__).parent.parent / "examples" / "09_cornell_homework.json"
#: each kind of student, with whether their image should pass
KINDS = {"exact": True, "offset 1e-3": True, "no shadows": False}


@dataclass(frozen=True)
class Student:
    name: str
    kind: str
    scene: bytes  # their own copy of the homework
    image: bytes  # their PNG


@dataclass
class Outcome:
    """What one student was answered: the last status (None: no answer at all), the grade, the tries made and
    the Retry-After of each 503 waited out."""

    student: Student
    status: int | None = None
    answer: dict[str, Any] = field(default_factory=dict)
    tries: int = 0
    waits: list[float] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def right(self) -> bool:
        return self.status == 200 and self.answer.get("passed") is KINDS[self.student.kind]


def copies(data: dict[str, Any], count: int, same: bool) -> list[bytes]:
    """``count`` students' copies of a scene: the same text, or each with a background a millionth brighter."""
    out = []
    for k in range(count):
        own = json.loads(json.dumps(data))
        if not same:
            base = own["image"].get("background", [0, 0, 0])
            base = [base] * 3 if isinstance(base, int | float) else base
            own["image"]["background"] = [float(c) + 1e-6 * (k + 1) for c in base]
        out.append(json.dumps(own).encode())
    return out


def kinds(count: int, seed: int) -> list[str]:
    """The class's kinds: 15 % offsets, 15 % no shadows, the rest exact, shuffled."""
    odd = round(0.15 * count)
    out = ["offset 1e-3"] * odd + ["no shadows"] * odd
    out += ["exact"] * (count - len(out))
    random.Random(seed).shuffle(out)
    return out


def image_of(scene: bytes, kind: str) -> bytes:
    """A student's PNG of their scene: exact, with an honest 1e-3 ray offset, or without shadow rays."""
    from schemas import load_scene
    from tracer import Renderer, encode_png
    from tracer.scene.variants import VARIANTS, Options

    options = {"exact": Options(), "offset 1e-3": Options(offset=1e-3), "no shadows": VARIANTS["no-shadows"][0]}
    return encode_png(Renderer(load_scene(scene), options[kind]).pixels())


def make_class(data: dict[str, Any], count: int, seed: int, same: bool, jobs: int = 2) -> list[Student]:
    """The class, each student's image rendered from their own copy (on ``jobs`` processes)."""
    scenes, their = copies(data, count, same), kinds(count, seed)
    done: dict[tuple[bytes, str], bytes] = {}
    with ProcessPoolExecutor(jobs) as pool:
        wanted = list(dict.fromkeys(zip(scenes, their, strict=True)))
        for key, png in zip(wanted, pool.map(image_of, *zip(*wanted, strict=True)), strict=True):
            done[key] = png
    pairs = enumerate(zip(scenes, their, strict=True))
    return [Student(f"s{k:02d}", kind, scene, done[(scene, kind)]) for k, (scene, kind) in pairs]


def form(scene: bytes, image: bytes) -> tuple[bytes, str]:
    b = "phongrayrush"
    data = (
        f'--{b}\r\nContent-Disposition: form-data; name="scene"\r\n\r\n'.encode()
        + scene
        + f'\r\n--{b}\r\nContent-Disposition: form-data; name="image"; filename="cornell.png"\r\n'
        f"Content-Type: image/png\r\n\r\n".encode()
        + image
        + f"\r\n--{b}--\r\n".encode()
    )
    return data, f"multipart/form-data; boundary={b}"


def graded(url: str, student: Student, tries: int, start: threading.Event) -> Outcome:
    """One student's grade: asked, and asked again after each 503's Retry-After (or a second after a lost
    connection), ``tries`` times at most."""
    out = Outcome(student)
    body, kind = form(student.scene, student.image)
    start.wait()
    began = time.monotonic()
    while out.tries < tries:
        out.tries += 1
        request = urllib.request.Request(url + "/grade", body, {"content-type": kind})
        try:
            with urllib.request.urlopen(request, timeout=3600) as res:
                out.status, out.answer = res.status, json.loads(res.read())
                break
        except urllib.error.HTTPError as exc:
            out.status, text = exc.code, exc.read()
            exc.close()
            out.answer = {"detail": text.decode(errors="replace")}
            if exc.code != 503:
                break
            out.waits.append(float(exc.headers.get("retry-after", "1")))
            time.sleep(out.waits[-1])
        except OSError:  # (a connection lost: tried again, as a 503)
            out.status = None
            time.sleep(1.0)
    out.seconds = time.monotonic() - began
    return out


def rush(url: str, students: list[Student], tries: int = 20) -> list[Outcome]:
    """Every student graded at once (a thread each, let go together)."""
    start = threading.Event()
    outcomes: list[Outcome | None] = [None] * len(students)

    def one(k: int) -> None:
        outcomes[k] = graded(url, students[k], tries, start)

    threads = [threading.Thread(target=one, args=(k,)) for k in range(len(students))]
    for t in threads:
        t.start()
    start.set()
    for t in threads:
        t.join()
    return [o for o in outcomes if o is not None]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def serving(workers: int, settings: dict[str, str], log: Path) -> Iterator[str]:
    """``phongray serve --workers N`` on 127.0.0.1 at a free port, with ``PHONGRAY_*`` settings; its URL."""
    port = free_port()
    env = {**os.environ, **{f"PHONGRAY_{k.upper()}": v for k, v in settings.items()}}
    command = [sys.executable, "-m", "service.cli", "serve", "--host", "127.0.0.1", "--port", str(port)]
    with open(log, "w") as out:
        proc = subprocess.Popen([*command, "--workers", str(workers)], env=env, stdout=out, stderr=subprocess.STDOUT)
        url = f"http://127.0.0.1:{port}"
        try:
            for _ in range(600):
                with contextlib.suppress(OSError), urllib.request.urlopen(url + "/healthz", timeout=1):
                    break
                time.sleep(0.1)
            else:
                raise RuntimeError(f"the server did not start (see {log})")
            yield url
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def table(outcomes: list[Outcome]) -> list[str]:
    """Each kind's outcomes, a line each, and the 503s waited out."""
    lines = [f"  {'kind':<12} students  right  wrong  never answered  tries (most)  'No diagnosis'  named"]
    for kind in KINDS:
        mine = [o for o in outcomes if o.student.kind == kind]
        if not mine:
            continue
        right = sum(o.right for o in mine)
        unanswered = sum(o.status != 200 for o in mine)
        blind = sum("No diagnosis" in json.dumps(o.answer) for o in mine)
        named = (
            sum("no-shadows" in json.dumps(o.answer.get("diagnosis") or {}) for o in mine) if not KINDS[kind] else ""
        )
        tries = f"{sum(o.tries for o in mine) / len(mine):.1f} ({max(o.tries for o in mine)})"
        lines.append(
            f"  {kind:<12} {len(mine):>8}  {right:>5}  {len(mine) - right - unanswered:>5}  {unanswered:>14}  "
            f"{tries:>12}  {blind:>13}  {named}"
        )
    waits = [w for o in outcomes for w in o.waits]
    lines.append(
        f"503s waited out: {len(waits)}"
        + (f" (Retry-After {min(waits):g}–{max(waits):g} s)" if waits else "")
        + f"; slowest student answered in {max(o.seconds for o in outcomes):.0f} s"
    )
    for o in outcomes:
        sentence = (o.answer.get("diagnosis") or {}).get("sentence", "")
        if not o.right or sentence.startswith("No diagnosis"):
            said = o.answer.get("reason") or o.answer.get("detail") or ""
            verdict = "right" if o.right else "WRONG"
            lines.append(f"  {o.student.name} ({o.student.kind}, {verdict}): {o.status} after {o.tries} tries: {said}")
            if sentence:
                lines.append(f"    {sentence}")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.rush", description=__doc__.split("\n\n")[0])
    parser.add_argument("--students", type=int, default=40)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--tries", type=int, default=20, help="tries of each client (503s waited out)")
    parser.add_argument("--scene", type=Path, default=HOMEWORK)
    parser.add_argument("--size", help="WxH: the homework at another size")
    parser.add_argument("--same-scene", action="store_true", help="every student with the very same scene")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a PHONGRAY_ setting")
    args = parser.parse_args(argv)
    data = json.loads(args.scene.read_text())
    if args.size:
        width, height = (int(v) for v in args.size.lower().split("x"))
        data["image"].update(width=width, height=height)
    settings = dict(item.split("=", 1) for item in args.set)
    began = time.monotonic()
    students = make_class(data, args.students, args.seed, args.same_scene)
    print(f"the class of {len(students)} made in {time.monotonic() - began:.0f} s", flush=True)
    with tempfile.TemporaryDirectory() as folder, serving(args.workers, settings, Path(folder) / "server.log") as url:
        began = time.monotonic()
        outcomes = rush(url, students, args.tries)
        took = time.monotonic() - began
        log = (Path(folder) / "server.log").read_text()
    print(
        f"rush: {len(students)} students at once on POST /grade ({args.scene.name}, "
        f"{data['image']['width']}×{data['image']['height']}, {'one scene' if args.same_scene else 'own copies'}), "
        f"{args.workers} workers, {args.tries} tries each, settings {settings or 'default'}, in {took:.0f} s"
    )
    for line in table(outcomes):
        print(line)
    print(f"'Traceback' in the server's log: {log.count('Traceback')}")
    right = all(o.right for o in outcomes)
    print(f"every student answered with the right verdict: {'yes' if right else 'NO'}")
    return 0 if right else 1


if __name__ == "__main__":
    sys.exit(main())
