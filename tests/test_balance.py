"""Connections spread over a server's workers (service/http/balance.py): the worker holding the fewest takes the
next."""

import http.client
import json
import os
import subprocess
import sys
import threading
import time

import pytest

from service.http.balance import PATIENCE, Board, balanced_loop
from service.settings import Settings

from server import running_server


def test_a_board_counts_each_workers_connections_and_names_whose_turn_it_is():
    board = Board.create()
    reader = Board(board.path)
    try:
        board.claim()
        # a second worker: a live child process that claims a slot and holds one connection
        child = subprocess.Popen(
            [
                sys.executable,
                "-c",
                (
                    "import sys, time; from service.http.balance import Board; b = Board(sys.argv[1]); b.claim(); "
                    "b.opened(); print(b.slot, flush=True); time.sleep(30)"
                ),
                board.path,
            ],
            stdout=subprocess.PIPE,
            text=True,
        )
        try:
            assert child.stdout is not None
            child_slot = int(child.stdout.readline())
            assert reader.counts() == {os.getpid(): 0, child.pid: 1}
            assert board.my_turn()  # 0 against 1
            board.opened()
            assert not board.my_turn()  # 1 against 1: the worker that accepted less recently (the child) takes it
            board._slots[board.slot, 2] = 0
            assert board.my_turn()  # 1 against 1, and this worker's last accept is the older
            board.opened()
            assert not board.my_turn()  # 2 against 1: the other worker's turn
            for _ in range(3):
                board.closed()  # (never below zero)
            assert reader.counts()[os.getpid()] == 0
            board.opened()
            board.opened()
        finally:
            child.kill()
            child.wait()
            child.stdout.close()
        assert board.my_turn()  # a dead worker's count does not hold the others back
        restarted = Board(board.path)
        restarted.claim()  # its slot goes to the next worker that starts
        assert restarted.slot == child_slot
        restarted.close()
    finally:
        reader.close()
        board.close()
        os.unlink(board.path)


def _worker_of(conn: http.client.HTTPConnection) -> int:
    conn.request("GET", "/healthz")
    return int(json.loads(conn.getresponse().read())["worker"])


def _connect_at_once(conn: http.client.HTTPConnection, barrier: threading.Barrier, reached: list[int]) -> None:
    barrier.wait()
    conn.connect()
    reached.append(_worker_of(conn))


#: how long a worker stands aside in these tests: the spreading is the board's to decide, not the machine's
#: scheduler (at the default 0.02 s a worker kept waiting by a busy machine is, rightly, passed over)
PATIENT = "5"


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory):
    with running_server(tmp_path_factory.mktemp("balance"), workers=2, balance_patience=PATIENT) as (url, _):
        port = int(url.rsplit(":", 1)[1])
        seen: set[int] = set()
        # both workers up: until two connections held at once have reached two workers (a second worker's start
        # is the machine's to time: it is waited for as the server itself is, but not forever)
        for _ in range(600):
            conns = [http.client.HTTPConnection("127.0.0.1", port, timeout=10) for _ in range(2)]
            reached = {_worker_of(c) for c in conns}
            for c in conns:
                c.close()
            seen |= reached
            if len(reached) == 2:
                break
            time.sleep(0.1)
        else:
            raise RuntimeError(f"the server's second worker did not start (workers seen: {sorted(seen)})")
        yield port


def test_two_kept_alive_clients_reach_two_workers(two_workers):
    """Two clients that connect at the same moment, a hundred times over, each pair closed just before the next
    connects (so that a worker may still count its last client): each time on two workers."""
    for _ in range(100):
        conns = [http.client.HTTPConnection("127.0.0.1", two_workers, timeout=10) for _ in range(2)]
        barrier = threading.Barrier(2)
        reached: list[int] = []

        threads = [threading.Thread(target=_connect_at_once, args=(c, barrier, reached)) for c in conns]
        try:
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            assert len(set(reached)) == 2, reached
            for _ in range(3):  # and they stay there
                assert sorted(_worker_of(c) for c in conns) == sorted(reached)
        finally:
            for c in conns:
                c.close()


def test_more_clients_than_workers_are_all_answered_and_spread_evenly(two_workers):
    conns = [http.client.HTTPConnection("127.0.0.1", two_workers, timeout=10) for _ in range(6)]
    try:
        reached = [_worker_of(c) for c in conns]  # one after the other: each to the worker holding fewer
        assert sorted(reached.count(w) for w in set(reached)) == [3, 3]
    finally:
        for c in conns:
            c.close()


def test_a_connection_waits_for_no_worker_longer_than_its_patience():
    assert 0 < PATIENCE <= 0.05
    assert Settings().balance_patience == PATIENCE


def test_a_worker_stands_aside_as_long_as_its_setting_says(monkeypatch):
    monkeypatch.setenv("PHONGRAY_BALANCE_PATIENCE", "3")
    loop = balanced_loop()
    try:
        assert loop.patience == 3.0
    finally:
        loop.close()
