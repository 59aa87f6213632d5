"""Moved to :mod:`receptance.diagnosis.compare` (the diagnosis is its own subpackage); this name keeps old imports working.

``import receptance.compare`` gives the very module ``receptance.diagnosis.compare``.
"""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("receptance.diagnosis.compare")
