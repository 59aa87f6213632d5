"""Wheelset designs other than the thesis's (Table 2.1), for testing that nothing is tuned to one wheelset.

The virtual lab's default :class:`~lab_data.wheelset.WheelsetParameters` is the
thesis's metro wheelset with axle-mounted brake discs. The toolkit must work
on any design FE, so the tests also run the lab workflow on:

``metro``
    A light metro/tram wheelset: 0.34 m rolling radius, 180 kg wheels,
    thinner axle, a small 90 kg disc, 60 kg axleboxes at ±1.00 m.
``freight``
    A heavy freight wheelset: 0.46 m rolling radius, 340 kg wheels, 400 kg
    axle, 95 kg axleboxes at ±1.00 m. Freight wheelsets brake on the tread;
    the generator needs a disc for its hammer and disc sensors, so a light
    25 kg plate stands in for it.

Both are plausible (masses and dimensions within the ranges of EN 13103 /
EN 13262 wheelsets); their spectra differ from the default's, so their
truncation frequencies must be chosen in a spectral gap
(:func:`lab_data.truth.check_spectral_gap`): the campaigns use
``fe_max_hz`` from :data:`DESIGN_FE_MAX_HZ`.
"""

from __future__ import annotations

from lab_data.wheelset import WheelsetParameters

__all__ = ["DESIGNS", "DESIGN_FE_MAX_HZ", "get_design"]

METRO = WheelsetParameters(
    axle_segments=((0.30, 0.140), (0.46, 0.170), (0.62, 0.135), (0.80, 0.180), (0.88, 0.150), (1.09, 0.120)),
    axle_mass=230.0,
    wheel_y=0.72, contact_y=0.75, wheel_mass=180.0, rolling_radius=0.34,
    hub_radius=0.12, hub_length=0.16, rim_radius=0.317, rim_radial=0.050, rim_axial=0.125,
    web_thickness=0.022,
    disc_y=0.38, disc_mass=90.0, disc_hub_radius=0.11, disc_outer_radius=0.27, disc_thickness=0.045,
    axlebox_y=1.00, axlebox_mass=60.0, axlebox_half_size=(0.13, 0.10, 0.13), axlebox_inertia=(0.55, 0.80, 0.55),
)

FREIGHT = WheelsetParameters(
    axle_segments=((0.30, 0.175), (0.46, 0.180), (0.62, 0.175), (0.82, 0.210), (0.90, 0.175), (1.10, 0.130)),
    axle_mass=400.0,
    wheel_y=0.72, contact_y=0.75, wheel_mass=340.0, rolling_radius=0.46,
    hub_radius=0.145, hub_length=0.18, rim_radius=0.429, rim_radial=0.065, rim_axial=0.135,
    web_thickness=0.028,
    disc_y=0.40, disc_mass=25.0, disc_hub_radius=0.11, disc_outer_radius=0.22, disc_thickness=0.02,
    axlebox_y=1.00, axlebox_mass=95.0, axlebox_half_size=(0.16, 0.12, 0.16), axlebox_inertia=(1.1, 1.6, 1.1),
)

DESIGNS: dict[str, WheelsetParameters] = {"default": WheelsetParameters(), "metro": METRO, "freight": FREIGHT}

#: truncation frequency of the truth per design and scenario family: it must fall in a gap of the spectrum
DESIGN_FE_MAX_HZ: dict[str, float] = {"default": 500.0, "metro": 510.0, "freight": 520.0}


def get_design(name: str) -> WheelsetParameters:
    """The named design's parameters (``KeyError`` lists the names)."""
    try:
        return DESIGNS[name]
    except KeyError:
        raise KeyError(f"unknown wheelset design {name!r}; known: {sorted(DESIGNS)}") from None
