"""Schemathesis against the service's own OpenAPI: no 5xx, and every answer matches the documentation.

The positive-data check is left out: the JSON Schema cannot state the format's
rules between values (look_at ≠ position, known material names, ...), so a
schema-valid scene may rightly be refused with a located 422.
"""

import json

import schemathesis
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from schemathesis.specs.openapi.checks import positive_data_acceptance
from starlette.testclient import TestClient

from service.http.app import create_app
from service.settings import Settings

from helpers import scene_dict

app = create_app(Settings(max_concurrent_renders=4, max_cost=2e6, render_timeout=5.0))
schema = schemathesis.openapi.from_asgi("/openapi.json", app)
SENT = {"requests": 0, "server_errors": 0}


@schema.parametrize()
@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
def test_api_conforms_to_its_openapi(case):
    response = case.call_and_validate(excluded_checks=[positive_data_acceptance])
    SENT["requests"] += 1
    SENT["server_errors"] += response.status_code >= 500
    assert response.status_code < 500


def test_fuzzing_sent_requests_and_saw_no_server_error():
    """Runs after the fuzzing above (pytest keeps file order): it did send requests, and none got a 5xx."""
    print(f"\nschemathesis: {SENT['requests']} requests, {SENT['server_errors']} answered 5xx")
    assert SENT["requests"] > 50 and SENT["server_errors"] == 0


# Every JSON value shape, anywhere in a scene, to every endpoint that reads a scene.

EDGES = [10**4000, -(10**4000), 2**63, 2**31, -1, 0, -0.0, 1e308, -1e308, 5e-324, 1e-300, 0.5, "\ud800", "a\udfff"]
ANY_TEXT = st.characters(exclude_categories=())  # lone surrogates included
json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.sampled_from(EDGES)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(ANY_TEXT),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(ANY_TEXT, max_size=8), inner, max_size=5),
    max_leaves=12,
)
fuzz_client = TestClient(create_app(Settings(max_concurrent_renders=4, max_cost=2e5, render_timeout=5.0)))


def small_scene() -> dict:
    data = scene_dict("02_all_lights")
    data["image"].update({"width": 16, "height": 12})
    return data


def places(value, path=()):
    """Every path to a value inside a parsed JSON document (the document itself is ``()``)."""
    yield path
    if isinstance(value, dict):
        for key, item in value.items():
            yield from places(item, (*path, key))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from places(item, (*path, i))


PLACES = list(places(small_scene()))


def replaced(path, value):
    data = small_scene()
    if not path:
        return value
    node = data
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value
    return data


@given(path=st.sampled_from(PLACES), value=json_values, endpoint=st.sampled_from(["/render", "/validate", "/grade"]))
@example(path=("objects", 0, "material"), value="\ud800", endpoint="/render")
@example(path=("materials",), value={"\udfff": 1}, endpoint="/validate")
@example(path=("image", "width"), value=10**4000, endpoint="/grade")
@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
def test_any_json_value_anywhere_never_gives_a_server_error(path, value, endpoint):
    body = json.dumps(replaced(path, value)).encode()  # ASCII escapes: lone surrogates survive
    if endpoint == "/grade":
        res = fuzz_client.post(endpoint, files={"scene": ("s.json", body), "image": ("a.png", b"\x89PNG\r\n\x1a\n")})
    else:
        res = fuzz_client.post(endpoint, content=body, headers={"content-type": "application/json"})
    assert res.status_code < 500, (path, value, res.text[:300])
    if res.headers.get("content-type", "").startswith("application/json"):
        res.json()
