"""What starting class grading's pool of processes costs: processes forked from phongray's forkserver (the pool
grade-class makes, service/classgrade/processes.py) against the same pool spawned as fresh interpreters.

    python -m bench.poolstart [--pools 5] [--processes 2]

Makes ``--pools`` pools of ``--processes`` processes one after the other, as a process that grades class after
class does (the service, a test session), each process rendering a tiny scene once, and prints as one JSON line
the CPU seconds the pools' processes took (their own and the forkserver's, which this process reaps at its end),
for each way and their ratio.  Each way runs in a fresh interpreter, so that neither finds the other's forkserver.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import resource
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

SCENE = Path(__file__).resolve().parent.parent / "tests" / "scenes" / "01_three_spheres.json"


def _tiny() -> bytes:
    data = json.loads(SCENE.read_text())
    data["image"].update({"width": 8, "height": 6, "samples": 1})
    return json.dumps(data).encode()


def one_way(way: str, pools: int, processes: int) -> float:
    """CPU seconds of ``pools`` pools of ``processes`` processes made ``way`` (forkserver or spawn), measured
    in this process, which must not have made a pool before."""
    from service.classgrade import processes as pool_processes
    from service.classgrade import tasks

    scene = _tiny()
    for _ in range(pools):
        if way == "forkserver":
            context = pool_processes.context()
            options = {"initializer": pool_processes.join, "initargs": pool_processes.initargs(context)}
        else:
            context, options = multiprocessing.get_context("spawn"), {}
        with ProcessPoolExecutor(processes, mp_context=context, **options) as pool:
            futures = [pool.submit(tasks.render_task, scene) for _ in range(processes)]
            assert all(f.result()[0] for f in futures)
    if way == "forkserver":
        from multiprocessing import forkserver

        forkserver._forkserver._stop()  # (reaped, so that its CPU time and its children's are counted)
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m bench.poolstart", description=__doc__.splitlines()[0])
    parser.add_argument("--pools", type=int, default=5)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--way", choices=["forkserver", "spawn"], help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.way:
        print(one_way(args.way, args.pools, args.processes))
        return
    seconds = {}
    for way in ("forkserver", "spawn"):
        command = [sys.executable, "-m", "bench.poolstart", "--way", way, "--pools", str(args.pools)]
        command += ["--processes", str(args.processes)]
        seconds[way] = float(subprocess.run(command, check=True, capture_output=True, text=True).stdout)
    print(
        json.dumps(
            {
                "pools": args.pools,
                "processes": args.processes,
                "forkserver_cpu_s": round(seconds["forkserver"], 2),
                "spawn_cpu_s": round(seconds["spawn"], 2),
                "spawn_over_forkserver": round(seconds["spawn"] / seconds["forkserver"], 1),
            }
        )
    )


if __name__ == "__main__":
    main()
