"""How long grading a large submission keeps a server's other requests waiting: the interpreter lock, stage by stage.

    python -m bench.stalls [--size 4096] [--rounds 6]

Grades a ``--size``² 16-bit RGBA deflate bomb (a few hundred KB that decode to size²×8 bytes) against a black
reference of that size, in this process, the way a service worker does: the allocator tuned as
``phongray serve`` tunes it, and the memory handed back to the OS after every grade.  Beside it a thread sleeps
1 ms at a time and records how late it wakes: a late wake is time during which the grade held the interpreter
lock, and during which a server's event loop could answer nothing.  It prints, per stage, the mean seconds
and the longest stall over ``--rounds`` grades, as one JSON line.
"""

from __future__ import annotations

import argparse
import json
import struct
import threading
import time
import zlib
from collections.abc import Callable
from typing import Any

import numpy as np

from service.work import pipeline
from tracer import decode_png, encode_png
from tracer.image import PNG_SIGNATURE, png_chunk
from tracer.memory import release, tune_allocator


def png_rgba16(width: int, height: int, alpha: int) -> bytes:
    """A 16-bit RGBA PNG of black pixels with the given alpha: a few hundred KB that decode to width×height×8 bytes."""
    row = b"\x00" + (b"\x00" * 6 + alpha.to_bytes(2, "big")) * width
    compressor = zlib.compressobj(9)
    idat = b"".join(compressor.compress(row) for _ in range(height)) + compressor.flush()
    ihdr = struct.pack(">IIBBBBB", width, height, 16, 6, 0, 0, 0)
    return PNG_SIGNATURE + png_chunk(b"IHDR", ihdr) + png_chunk(b"IDAT", idat) + png_chunk(b"IEND", b"")


class Sleeper:
    """A thread that sleeps 1 ms at a time; :meth:`worst` is its latest wake since the last :meth:`reset`."""

    def __init__(self) -> None:
        self.late = 0.0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        last = time.perf_counter()
        while not self.stop.is_set():
            time.sleep(0.001)
            now = time.perf_counter()
            self.late = max(self.late, now - last - 0.001)
            last = now

    def reset(self) -> None:
        self.late = 0.0

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


def stalls(size: int, rounds: int) -> dict[str, Any]:
    tune_allocator(1)  # as a service worker asks for it
    bomb = png_rgba16(size, size, 65535)
    reference = encode_png(np.zeros((size, size, 3), np.uint8))
    seconds: dict[str, float] = {}
    worst: dict[str, float] = {}
    sleeper = Sleeper()

    def stage(name: str, work: Callable[[], Any]) -> Any:
        sleeper.reset()
        started = time.perf_counter()
        out = work()
        seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - started
        worst[name] = max(worst.get(name, 0.0), sleeper.late)
        return out

    def grade() -> None:
        submitted = stage("decode the submission", lambda: pipeline.read_image(bomb, (size, size)))
        pixels = stage("decode the reference", lambda: decode_png(reference))
        stage("compare", lambda: pipeline.compare(reference, submitted, 2.0, 0.001, reference=pixels))

    try:
        time.sleep(0.05)
        for _ in range(rounds):
            grade()  # its images are freed when it returns
            stage("hand memory back", release)
    finally:
        sleeper.close()
    table = {
        name: {"mean_s": round(seconds[name] / rounds, 3), "worst_stall_ms": round(1000 * worst[name], 1)}
        for name in seconds
    }
    return {"size": size, "rounds": rounds, "bomb_bytes": len(bomb), "stages": table}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=4096, help="the image's width and height (default 4096)")
    parser.add_argument("--rounds", type=int, default=6, help="grades to time (default 6)")
    args = parser.parse_args()
    print(json.dumps(stalls(args.size, args.rounds)))


if __name__ == "__main__":
    main()
