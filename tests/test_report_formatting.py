"""The reports' one cell formatter: what a practitioner reads for missing, infinite and boolean values."""

import numpy as np

from estimator.html import fmt_number, table_html
from receptance.formatting import format_value


def test_format_value_cases():
    assert format_value(None) == "–"
    assert format_value(float("nan")) == "–"
    assert format_value(np.inf) == "∞" and format_value(-np.inf) == "−∞"
    assert format_value(np.bool_(True)) == "yes" and format_value(False) == "no"
    assert format_value(np.int64(12345678)) == "12345678"  # integers are never rounded
    assert format_value(3.14159265) == "3.142" and format_value(3.14159265, 6) == "3.14159"
    assert format_value("L & R") == "L & R"  # plain text: the report escapes it


def test_field_cells_are_escaped_once():
    assert fmt_number("L & R") == "L &amp; R"
    assert fmt_number(-np.inf) == "−∞"
    import pandas as pd

    html = table_html(pd.DataFrame({"rail": ["<L>"], "pk-pk": [1.23456]}))
    assert "&lt;L&gt;" in html and "<td class='num'>1.235</td>" in html
