"""Moved to :mod:`receptance.diagnosis.diagnose` (the diagnosis is its own subpackage); this name keeps old imports working.

``import receptance.diagnose`` gives the very module ``receptance.diagnosis.diagnose``.
"""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("receptance.diagnosis.diagnose")
