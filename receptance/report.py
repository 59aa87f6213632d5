"""Moved to :mod:`receptance.diagnosis.report` (the diagnosis is its own subpackage); this name keeps old imports working.

``import receptance.report`` gives the very module ``receptance.diagnosis.report``.
"""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("receptance.diagnosis.report")
