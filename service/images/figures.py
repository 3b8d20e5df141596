"""Numbers as every report shows them: a fraction as a percent, a count with its noun."""

from __future__ import annotations


def percent(fraction: float) -> str:
    """``0.0123`` → ``1.23 %`` (small fractions keep two significant digits: ``0.0012 %``)."""
    value = 100 * fraction
    if value == 0 or value >= 0.01:
        return f"{value:.2f} %"
    return f"{value:.2g} %"


def counted(n: int, noun: str) -> str:
    """``n`` and the noun, plural but for one: "1 pair", "3 pairs", "0 references"."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"
