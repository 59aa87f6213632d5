"""receptance — hybrid modal model, track and contact receptances, measurement transfer functions.

Role in the data flow (``shared/DESIGN.md``): combines FE shapes from
:mod:`fem_import` with the test frequencies and damping from :mod:`ema`
(thesis §2.3), adds physical effects (residuals, primary suspension,
bearings, ...) as structural modifications, computes the Timoshenko track
receptance (§2.4) and the Hertzian contact stiffness, and forms the
half-wheelset, full vertical and full vertical+lateral transfer functions
(eqs. 2.6, 2.11, 2.22) that :mod:`estimator` inverts.
"""

# Built so far (issue 4 in progress): contact stiffness and track receptance.
from .contact import ContactParameters, HertzContact, hertz_compliance, hertz_contact, hertz_stiffness
from .track import track_frf, track_receptance
from .trackform import Trackform, TrackformError, load_trackform

__all__ = [
    "ContactParameters", "HertzContact", "hertz_compliance", "hertz_contact", "hertz_stiffness",
    "track_frf", "track_receptance",
    "Trackform", "TrackformError", "load_trackform",
]
