"""A worker's render slots (service/work/slots.py): taken in turn, waited for at most queue_wait, left by a
client that goes, and a Retry-After that reflects the queue; a grade whose accepted variants wait for a slot
is decided, never failed for the load."""

from __future__ import annotations

import json
import threading
import time

import pytest
from fastapi.testclient import TestClient

import schemas
import tracer
from service.http.app import create_app
from service.settings import Settings
from service.work.slots import Busy, Slots
from tracer import RenderCancelled, Renderer
from tracer.scene.variants import Options

from helpers import scene_dict


def _until(test, what: str) -> None:
    """Wait until ``test()`` (a state of the objects under test, not a time): a hang fails after long."""
    for _ in range(6000):
        if test():
            return
        time.sleep(0.01)
    raise AssertionError(f"never: {what}")


def _waiter(slots: Slots, order: list[int], k: int, **kwargs) -> threading.Thread:
    def run() -> None:
        try:
            taken = slots.take(**kwargs)
        except (Busy, RenderCancelled) as exc:
            order.append(-k if isinstance(exc, Busy) else 100 + k)
            return
        order.append(k)
        slots.give(taken)

    thread = threading.Thread(target=run)
    thread.start()
    return thread


def test_slots_are_handed_out_in_the_order_they_were_asked_for():
    slots = Slots(1, wait=600)
    held = slots.take()
    order: list[int] = []
    threads = []
    for k in range(1, 6):
        threads.append(_waiter(slots, order, k))
        _until(lambda k=k: slots.waiting == k, f"{k} waiting")  # (each asks after the one before)
    assert order == []
    slots.give(held)
    for t in threads:
        t.join()
    assert order == [1, 2, 3, 4, 5]
    assert slots.take() is not None and slots.waiting == 0  # (every slot given back)


def test_a_freed_slot_goes_to_the_longest_waiting_not_to_a_newcomer():
    slots = Slots(1, wait=600)
    held = slots.take()
    order: list[int] = []
    waiter = _waiter(slots, order, 1)
    _until(lambda: slots.waiting == 1, "one waiting")
    slots.give(held)
    waiter.join()
    assert order == [1]
    again = slots.take()  # (free once the waiter gave it back)
    slots.give(again)


def test_work_that_waits_past_queue_wait_is_busy_and_leaves_the_queue():
    slots = Slots(1, wait=0.2)
    held = slots.take()
    with pytest.raises(Busy):
        slots.take()
    assert slots.waiting == 0
    slots.give(held)
    slots.give(slots.take())


def test_no_wait_is_busy_at_once():
    slots = Slots(1, wait=0)
    held = slots.take()
    with pytest.raises(Busy):
        slots.take()
    slots.give(held)
    with pytest.raises(Busy):
        Slots(0, wait=600).take()


def test_a_waiter_whose_client_left_leaves_the_queue_and_the_next_is_served():
    slots = Slots(1, wait=600)
    held = slots.take()
    order: list[int] = []
    left = threading.Event()
    first = _waiter(slots, order, 1, cancelled=left.is_set)
    _until(lambda: slots.waiting == 1, "one waiting")
    second = _waiter(slots, order, 2)
    _until(lambda: slots.waiting == 2, "two waiting")
    left.set()
    first.join()
    assert order == [101] and slots.waiting == 1  # (cancelled, out of the queue)
    slots.give(held)
    second.join()
    assert order == [101, 2]


def test_retry_after_reflects_the_queue_by_the_slots_holding_times():
    now = [0.0]
    slots = Slots(2, wait=600, clock=lambda: now[0])
    assert slots.retry_after(1) == 1  # (nothing held yet: the least)
    taken = slots.take()
    now[0] += 10.0
    slots.give(taken)
    assert slots.retry_after(1) == 5  # one held 10 s; this one's own turn over 2 slots
    a, b = slots.take(), slots.take()
    order: list[int] = []
    waiters = []
    for k in range(1, 4):
        waiters.append(_waiter(slots, order, k))
        _until(lambda k=k: slots.waiting == k, f"{k} waiting")
    assert slots.retry_after(1) == 20  # three waiting and this one: 4 × 10 s over 2 slots
    assert slots.retry_after(30) == 30
    slots.give(a)
    slots.give(b)
    for w in waiters:
        w.join()


# -- a grade in a busy worker -----------------------------------------------------------------------------------


#: what the honest image passes as: its offset in the scene's units, as a student would write it
ACCEPTED = "a ray offset of 0.005 along the normal"


@pytest.fixture(scope="module")
def offset():
    """The scene, and an honest tracer's image of it (a ray offset of 1e-3 of the visible size, 0.005 in the
    scene's units: it fails the reference, and passes as the accepted variant)."""
    data = scene_dict("04_whitted")
    data["image"].update(width=80, height=60)
    scene = schemas.validate_scene(data)
    return json.dumps(data), tracer.encode_png(Renderer(scene, Options(offset=1e-3)).pixels())


def _grade(api: TestClient, scene: str, image: bytes) -> object:
    return api.post("/grade", data={"scene": scene}, files={"image": ("s.png", image, "image/png")})


def test_a_grade_waits_its_turn_for_a_slot_and_passes_as_its_accepted_variant(offset):
    scene, image = offset
    api = TestClient(create_app(Settings(max_concurrent_renders=1)))
    assert api.post("/render", content=scene, headers={"content-type": "application/json"}).status_code == 200
    slots = api.app.state.service.slots
    held = slots.take()  # (every slot of the worker busy)
    answers: list = []
    asking = threading.Thread(target=lambda: answers.append(_grade(api, scene, image)))
    asking.start()
    _until(lambda: slots.waiting == 1, "the grade waiting for a slot")
    slots.give(held)
    asking.join()
    (res,) = answers
    assert res.status_code == 200, res.text
    answer = res.json()
    assert answer["passed"] is True and answer["accepted"] == ACCEPTED, answer


def test_a_grade_that_gets_no_slot_in_time_is_503_with_retry_after_never_a_fail(offset):
    scene, image = offset
    api = TestClient(create_app(Settings(max_concurrent_renders=1, queue_wait=0)))
    assert api.post("/render", content=scene, headers={"content-type": "application/json"}).status_code == 200
    slots = api.app.state.service.slots
    held = slots.take()
    try:
        res = _grade(api, scene, image)
    finally:
        slots.give(held)
    assert res.status_code == 503, res.text
    assert "every render slot is busy" in res.json()["detail"] and int(res.headers["retry-after"]) >= 1
    assert "(1 render at once; this one waited longer than queue_wait = 0 s)" in res.json()["detail"], res.text
    assert _grade(api, scene, image).json()["accepted"] == ACCEPTED  # (once a slot is free)
