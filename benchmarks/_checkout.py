"""Put the checkout this benchmark lives in (and its ``tests`` helpers) first on ``sys.path``.

A benchmark measures the code beside it. An editable install may point at another checkout (a clean clone made
to run the suite, an older tree), and a figure measured on that code would be printed as this one's.
Imported for its effect, before any of the toolkit's packages: ``import _checkout  # noqa: F401``.
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT / "tests", ROOT):
    if str(_p) in sys.path:
        sys.path.remove(str(_p))
    sys.path.insert(0, str(_p))
