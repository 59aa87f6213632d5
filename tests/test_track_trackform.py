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
