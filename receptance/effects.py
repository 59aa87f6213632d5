"""Moved to :mod:`receptance.diagnosis.effects` (the diagnosis is its own subpackage); this name keeps old imports working.

``import receptance.effects`` gives the very module ``receptance.diagnosis.effects``.
"""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("receptance.diagnosis.effects")
