"""Trackform parameters (thesis Table 2.2): SI defaults, TOML/JSON loading and validation."""

import json

import numpy as np
import pytest

from receptance.track import support_stiffness_per_metre
from receptance.trackform import Trackform, TrackformError, load_trackform, trackform_to_dict


def _toml(d):
    return "[trackform]\n" + "".join(f"{k} = {v!r}\n" for k, v in d.items())


def test_defaults_are_table_2_2_in_si():
    tf = Trackform()
    assert tf.rail_I_yy == pytest.approx(1844e-8) and tf.rail_I_zz == pytest.approx(362.4e-8)
    assert tf.rail_area == pytest.approx(63.62e-4) and tf.youngs_modulus == pytest.approx(206e9)
    assert tf.pad_stiffness_z == pytest.approx(150e6) and tf.subplate_stiffness_y == pytest.approx(10.3e6)
    # eq. 2.34 at 0 Hz: the two layers in series, per metre (K / L_s)
    k0 = support_stiffness_per_metre(0.0, tf, "vertical")
    krp, ksp = 150e6 / 0.75 * (1 + 0.13j), 30e6 / 0.75 * (1 + 0.2j)
    assert k0 == pytest.approx(krp * ksp / (krp + ksp), rel=1e-12)
    # at high frequency the baseplate mass blocks the subplate: k_eq -> k_rp + jΩ C_rp / L_s
    f = 1e6
    assert support_stiffness_per_metre(f, tf) == pytest.approx(krp + 2j * np.pi * f * 1.5e3 / 0.75, rel=1e-3)


@pytest.mark.parametrize("fmt", ["toml", "json"])
def test_round_trip(tmp_path, fmt):
    d = trackform_to_dict(Trackform())
    d["pad_stiffness_z"] = 120e6
    p = tmp_path / f"track.{fmt}"
    p.write_text(_toml(d) if fmt == "toml" else json.dumps(d))
    tf = load_trackform(p)
    assert tf == Trackform(pad_stiffness_z=120e6)


@pytest.mark.parametrize("edit, match", [
    (lambda d: d.update(pad_stifness_z=1.0), "unknown trackform key.*pad_stifness_z"),
    (lambda d: d.pop("baseplate_mass"), "missing trackform key.*baseplate_mass"),
    (lambda d: d.update(shear_factor=-0.34), "'shear_factor' must be finite and > 0"),
    (lambda d: d.update(rail_mass="heavy"), "'rail_mass' must be a number"),
])
def test_validation_names_key_and_file(tmp_path, edit, match):
    d = trackform_to_dict(Trackform())
    edit(d)
    p = tmp_path / "bad_track.json"
    p.write_text(json.dumps(d))
    with pytest.raises(TrackformError, match=match) as exc:
        load_trackform(p)
    assert "bad_track.json" in str(exc.value)


def test_bad_extension_and_syntax(tmp_path):
    p = tmp_path / "t.yaml"
    p.write_text("x: 1")
    with pytest.raises(TrackformError, match=r"t\.yaml.*'\.toml', '\.json'"):
        load_trackform(p)
    p = tmp_path / "t.toml"
    p.write_text("rail_mass = = 3")
    with pytest.raises(TrackformError, match=r"t\.toml: cannot parse"):
        load_trackform(p)


def test_constructor_validates():
    with pytest.raises(TrackformError, match="support_spacing"):
        Trackform(support_spacing=0.0)


def test_eq_2_34_is_pad_in_series_with_loaded_subplate():
    """1/k_eq = 1/Z_pad + 1/(Z_sub − Ω² M_p/L_s), Z = k*(1+jη) + jΩC/L_s, at all frequencies."""
    tf = Trackform()
    f = np.geomspace(1, 5000, 50)
    w = 2 * np.pi * f
    for d, (K1, C1, K2, C2) in {"vertical": (150e6, 1.5e3, 30e6, 2.8e3),
                               "lateral": (51.71e6, 0.75e3, 10.3e6, 1.4e3)}.items():
        z1 = K1 / 0.75 * (1 + 0.13j) + 1j * w * C1 / 0.75
        z2 = K2 / 0.75 * (1 + 0.20j) + 1j * w * C2 / 0.75 - w**2 * 15 / 0.75
        np.testing.assert_allclose(support_stiffness_per_metre(f, tf, d), 1 / (1 / z1 + 1 / z2), rtol=1e-12)


def test_causal_layers_obey_bode_and_meet_eq_2_32_at_the_reference():
    """Constant-loss layers: phase arctan(eta) everywhere and the gain slope Bode's relation ties to it.

    Oracle: for a causal minimum-phase law whose log-gain has a constant slope ``s`` per neper, Bode's
    gain-phase relation gives the phase ``π s / 2`` exactly; eq. 2.32's phase is ``arctan η``, so the slope
    must be ``2 arctan(η)/π`` — independent of how the law is written.
    """
    ref = 120.0
    # no dampers, a negligible baseplate: the support is the two layers in series
    bare = dict(pad_damping_z=1e-9, subplate_damping_z=1e-9, baseplate_mass=1e-6, loss_reference_hz=ref)
    f = np.geomspace(2.0, 2000.0, 40)
    # one layer at a time: the other made rigid
    for layer, eta in ((dict(subplate_stiffness_z=1e11), 0.13), (dict(pad_stiffness_z=1e11), 0.20)):
        k = support_stiffness_per_metre(f, Trackform(**bare, **layer))
        phase = np.angle(k)
        slope = np.gradient(np.log(np.abs(k)), np.log(f))
        np.testing.assert_allclose(phase, np.arctan(eta), atol=2e-3)
        np.testing.assert_allclose(slope, 2 * phase / np.pi, atol=2e-3)
    # at the reference the layers are eq. 2.32's; without a reference nothing changes; below 1 Hz no creep to 0
    krp, ksp = 150e6 / 0.75 * (1 + 0.13j), 30e6 / 0.75 * (1 + 0.2j)
    assert support_stiffness_per_metre(ref, Trackform(**bare)) == pytest.approx(krp * ksp / (krp + ksp), rel=1e-6)
    np.testing.assert_array_equal(support_stiffness_per_metre(f, Trackform()),
                                  support_stiffness_per_metre(f, Trackform(loss_reference_hz=None)))
    low = support_stiffness_per_metre(np.array([0.0, 0.5, 1.0]), Trackform(**bare))
    assert low[0] == pytest.approx(low[2], rel=1e-6) and low[1] == pytest.approx(low[2], rel=1e-6)
    # from 10 Hz to 1 kHz the subplate-dominated support stiffens by 2·ln(100)·arctan(0.2)/π ≈ 0.58 neper ≈ 5 dB
    k10, k1k = np.abs(support_stiffness_per_metre(np.array([10.0, 1000.0]), Trackform(**bare)))
    eq_2_32 = Trackform(**{**bare, "loss_reference_hz": None})
    nominal = np.abs(support_stiffness_per_metre(np.array([10.0, 1000.0]), eq_2_32))
    gain_db = 20 * np.log10(k1k / k10) - 20 * np.log10(nominal[1] / nominal[0])
    assert 3.5 < gain_db < 5.5


def test_loss_reference_is_optional_in_files(tmp_path):
    d = trackform_to_dict(Trackform())
    assert "loss_reference_hz" not in d
    p = tmp_path / "t.json"
    p.write_text(json.dumps(d))
    assert load_trackform(p).loss_reference_hz is None
    p.write_text(json.dumps({**d, "loss_reference_hz": 100.0}))
    assert load_trackform(p) == Trackform(loss_reference_hz=100.0)
    assert trackform_to_dict(Trackform(loss_reference_hz=100.0))["loss_reference_hz"] == 100.0
    p.write_text(json.dumps({**d, "loss_reference_hz": -5.0}))
    with pytest.raises(TrackformError, match="loss_reference_hz"):
        load_trackform(p)
