"""The bench's latency budgets (bench/budgets.py) and the tests that measure them stay in step: every budget
names a measurement some test makes, and a missed budget is reported."""

from pathlib import Path

from bench import budgets

TESTS = Path(__file__).parent


def test_every_named_budget_is_measured_by_a_test():
    sources = "".join((TESTS / name.split("::")[0].removeprefix("tests/")).read_text() for name in budgets.TESTS)
    exact = [pattern for pattern, limit in budgets.BUDGETS if "*" not in pattern]
    assert exact and all(f'"{name}"' in sources for name in exact), [n for n in exact if f'"{n}"' not in sources]
    # a pattern's first words are in a test (an attack's and a hostile request's names are given to a helper)
    words = [
        pattern.split("*")[0].removeprefix("attack ").removeprefix("hostile ")
        for pattern, _ in budgets.BUDGETS
        if "*" in pattern
    ]
    assert all(w in sources for w in words), [w for w in words if w not in sources]


def test_the_worst_of_each_measurement_is_held_against_its_budget():
    lines = [
        '{"name": "attack 10⁶ empty objects (3 MB) → /validate: answered (s)", "value": 0.5}',
        '{"name": "attack 10⁶ empty objects (3 MB) → /validate: answered (s)", "value": 2.5}',
        '{"name": "100 identical renders at once: worst /healthz (ms)", "value": 40}',
        '{"name": "attack lone surrogate: answered (s)", "value": 0.1}',
        "",
    ]
    measured = budgets.worst(lines)
    assert measured["attack 10⁶ empty objects (3 MB) → /validate: answered (s)"] == 2.5
    rows, missed = budgets.table(measured)
    assert missed == 1 and sum("MISSED" in row for row in rows) == 1
    assert "| 100 identical renders at once: worst /healthz (ms) | 40 | 100 |  |" in rows
    assert "| attack lone surrogate: answered (s) | 0.1 | — |  |" in rows  # shown, with no budget
    assert budgets.budget_of("48 concurrent 16 MiB grades: worst /healthz (ms)") == 250  # (the first that matches)
    assert "a hostile class: graded in (s)" in budgets.unmeasured(measured)
