"""The field model needs every mode of the wheelset, not only the test band's.

Oracle: the virtual line's own vehicle (``lab_data.line.vehicle``), built independently from the truth
wheelset's FE modes to 3 kHz plus the static flexibility of the modes above. The estimator's half-model
transfer from axlebox acceleration to irregularity (thesis eq. 2.6: ``(α_W + α_R + 1/k_H) / (−ω² α_B)``)
is compared with the same expression built from the line's receptances, with one track and contact.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from test_estimator_synthetic import lab_workflow_model

FREQS = np.arange(50.0, 401.0, 10.0)


def _half_transfer(contact_receptance, axlebox_receptance):
    from receptance import ContactParameters, Trackform
    from receptance.track import track_receptance

    rail = np.array([track_receptance(f, Trackform(), "vertical") for f in FREQS])
    return (contact_receptance + rail + 1 / ContactParameters().stiffness()) / axlebox_receptance


@pytest.fixture(scope="module")
def line_transfer():
    from lab_data.line.vehicle import build_vehicle

    v = build_vehicle()
    # wheelset 1, left wheel: vertical contact force (input 1) -> contact point z, axlebox centre z
    rows = np.stack([v.contact_out[1], v.point_shapes[0, 0, 2]])
    H = v.receptance(rows, FREQS)
    return _half_transfer(H[0, 1] + v.contact_residual[1, 1], H[1, 1])


def _model_transfer(model):
    pr = model.pole_residues(["contact_L:z", "axlebox_L:z"], ["contact_L:z"])
    s = 2j * np.pi * FREQS
    H = (pr.residues[:, :, :, None] / (s[None, None, None, :] - pr.poles[None, None, :, None])).sum(axis=2)
    return _half_transfer(H[0, 0], H[1, 0])


def test_in_service_puts_the_modes_above_the_test_band_into_the_receptances(line_transfer):
    from estimator.workflow import in_service

    lab = lab_workflow_model(2000.0, 500.0)  # as the lab diagnosis saves it
    field = in_service(lab)
    assert field.max_hz is None and "enter the receptances" in field.history[-1]
    err = 20 * np.log10(np.abs(_model_transfer(field) / line_transfer))
    # the design FE's modes to 2 kHz: within 0.5 dB of the line's vehicle over the whole inversion band (the
    # modes above 2 kHz and the design-vs-truth differences are what is left)
    assert np.max(np.abs(err)) < 0.5, dict(zip(FREQS, np.round(err, 2)))
    # kept to the test band, the same model misses the wheel's flexibility at the contact: > 2 dB near 300 Hz
    err_capped = 20 * np.log10(np.abs(_model_transfer(replace(field, max_hz=500.0)) / line_transfer))
    assert np.max(err_capped[(FREQS >= 250) & (FREQS <= 350)]) > 2.0
    assert np.max(np.abs(err_capped)) > 3 * np.max(np.abs(err))


def test_a_model_whose_modes_stop_at_the_band_is_flagged_in_the_estimate():
    from estimator.workflow import in_service, modal_basis

    short_note, short = modal_basis(in_service(lab_workflow_model(None, None)), 400.0)  # FE export to 500 Hz
    assert short and "elastic modes up to 425 Hz" in short_note and ">= 1200 Hz" in short_note
    note, flagged = modal_basis(in_service(lab_workflow_model(2000.0, 500.0)), 400.0)
    assert not flagged and "up to 1960 Hz" in note
