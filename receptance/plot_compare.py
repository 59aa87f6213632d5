"""Moved to :mod:`receptance.diagnosis.plot_compare` (the diagnosis is its own subpackage); this name keeps old imports working.

``import receptance.plot_compare`` gives the very module ``receptance.diagnosis.plot_compare``.
"""

import importlib
import sys

sys.modules[__name__] = importlib.import_module("receptance.diagnosis.plot_compare")
