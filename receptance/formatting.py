"""Plain-text formatting of table cells and figures in prose, shared by the lab and field reports.

The HTML reports (:mod:`receptance.diagnosis.report`, :mod:`estimator.html`) escape the text this returns;
it holds no markup of its own.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["format_value"]


def format_value(v, digits: int = 4) -> str:
    """A value as text: numbers with ``digits`` significant digits, '–' for missing or NaN, '∞' / '−∞' for an
    infinite number, yes/no for booleans, anything else as ``str``."""
    if v is None:
        return "–"
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(x):
        return "–" if math.isnan(x) else ("∞" if x > 0 else "−∞")
    return f"{x:.{digits}g}"
