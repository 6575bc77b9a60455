"""How the command line prints a figure: a length with its unit, a percentage with significant digits.

A fixed number of decimals printed an exact result's 1e-6 mm as "0.000%": a figure too small for the digits must
still show its size, so small ones go to exponent form.
"""

from __future__ import annotations

import math

#: Below this magnitude a figure is printed in exponent form (1.0e-06): "0.0001234" hides its size in zeros.
EXPONENT_BELOW = 1e-3


#: --units: what the summaries call each unit.
UNIT_LABELS = {"mm": "mm", "inch": "in", "m": "m"}


def number(x: float | None, digits: int = 4) -> str:
    """``x`` with ``digits`` significant digits; tiny values as 1.0e-06 (two digits: they are round-off-level
    figures), never as 0.000; None, NaN or infinity as "n/a"."""
    if x is None or not math.isfinite(x):
        return "n/a"
    if x == 0:
        return "0"
    if abs(x) < EXPONENT_BELOW:
        return f"{x:.1e}"
    return f"{x:.{digits}g}"


def length(x: float | None, unit: str = "mm") -> str:
    """A length with its unit: "0.01234 mm", "1.0e-06 mm", "n/a"."""
    text = number(x)
    return text if text == "n/a" else f"{text} {unit}"


def percent(x: float | None) -> str:
    """A percentage of the diagonal: "0.0617 %", "1.3e-06 %"."""
    text = number(x, 3)
    return text if text == "n/a" else f"{text} %"


def deviation_line(way: str, stats, diagonal: float, unit: str = "mm") -> str:
    """One direction of a deviation: max, p95 and RMS, each as a length and as a share of the diagonal.

    ``stats`` : mapping with ``max``, ``p95``, ``rms`` (lengths) and ``max_pct``, ``p95_pct``, ``rms_pct``.
    """
    parts = [f"{key} {length(stats[key], unit)} ({percent(stats[f'{key}_pct'])} of diagonal)"
             for key in ("max", "p95", "rms")]
    return f"deviation {way}: " + ", ".join(parts) + f"; diagonal {length(diagonal, unit)}"
