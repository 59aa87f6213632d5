"""railmodal: wheelset experimental modal analysis, hybrid receptance models and rail corrugation estimation.

This package holds only the command-line interface; the toolkit lives in the
top-level packages ``fem_import``, ``ema``, ``receptance`` and ``estimator``,
and the virtual lab in ``lab_data``.
"""

__version__ = "0.1.0"
