"""Schemathesis against the service's own OpenAPI: no 5xx, and every answer matches the documentation.

The positive-data check is left out: the JSON Schema cannot state the format's
rules between values (look_at ≠ position, known material names, ...), so a
schema-valid scene may rightly be refused with a located 422.
"""

import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.specs.openapi.checks import positive_data_acceptance

from service.app import create_app
from service.settings import Settings

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
