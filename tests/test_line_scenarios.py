"""Field scenarios of the virtual line: each hidden effect acts where, and only where, its truth says.

Every scenario's short campaign (one forward run over the first curve,
same seed) is compared with ``nominal``'s: everything but the effect is the
same realisation (rails, wheels, speed, sensor noise), so the difference of
the recorded channels isolates the effect. Not bit for bit: two campaigns
generated in different processes differ by rounding (the time-stepping
kernel is compiled with fast-math vectorised sums), which the non-linear
time stepping carries to a few ADC counts (measured: 1.1 LSB RMS and
5 LSB at most on the channels an effect does not touch; the effects move
their channels by 10^3 to 10^4 LSB RMS). So the untouched channels are
compared to 1 % of the sensor noise. Oracles: the truth manifest's
parameters (where the effect is, which channel, which polygon order) and
kinematics (a polygon of order n on a wheel of radius r excites
``n v / (2 π r)``).
"""

import numpy as np
import pytest

from lab_data.line.cache import line_campaign_dir
from lab_data.line.campaign import FIRST_CURVE_SECTION
from lab_data.line.files import read_run_truth, read_truth

pytestmark = pytest.mark.slow

CONFIG = dict(days=1, runs_per_day=1, section=FIRST_CURVE_SECTION)
ACC = ("ACC_W1L_Z", "ACC_W1R_Z", "ACC_W1L_Y", "ACC_W2L_Z", "ACC_W2R_Z", "ACC_W2R_Y")


def load(scenario):
    from asammdf import MDF

    folder = line_campaign_dir(scenario, **CONFIG)
    truth = read_truth(folder)
    run = truth["runs"][0]
    with MDF(folder / run["file"]) as m:
        data = {n: m.get(n).samples.astype(float) for n in ACC}
    pos = read_run_truth(folder, run["run_id"])
    return truth, data, pos


@pytest.fixture(scope="module")
def nominal():
    return load("nominal")


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def assert_untouched(truth, data, ref, effect_channels):
    """Every channel but ``effect_channels`` differs from nominal's record by less than 1 % of the sensor noise RMS
    (numerical rounding only; the effect itself is well above the noise)."""
    noise_g = truth["daq"]["noise_rms"] / 9.80665
    for n in ACC:
        if n not in effect_channels:
            assert rms(data[n] - ref[n]) < 0.01 * noise_g, n


def test_lateral_sign_flips_one_channel_only(nominal):
    truth, data, _ = load("lateral_sign")
    assert truth["scenario"]["sign_flips"] == ["ACC_W1L_Y"]
    assert [s["sign"] for s in truth["sensors"] if s["name"] == "ACC_W1L_Y"] == [-1.0]
    _, ref, _ = nominal
    # same noise realisation n (added after the sensor): recorded -s + n here, s + n in nominal, so the sum is
    # twice the noise (0.03 m/s^2 RMS) and the half difference is the flipped signal, well above the noise
    flipped, plain = data["ACC_W1L_Y"] * 9.80665, ref["ACC_W1L_Y"] * 9.80665
    assert rms(flipped + plain) == pytest.approx(2 * 0.03, rel=0.1)
    assert rms(plain - flipped) / 2 > 2 * 0.03  # the lateral signal is ~0.11 m/s^2 RMS here
    assert np.corrcoef(flipped, plain)[0, 1] < -0.5
    assert_untouched(truth, data, ref, {"ACC_W1L_Y"})


def test_sensor_offset_changes_that_accelerometer_only(nominal):
    truth, data, _ = load("sensor_offset")
    moved = [s for s in truth["sensors"] if s["name"] == "ACC_W1L_Z"][0]
    assert moved["offset_m"] == pytest.approx([0.0, -0.040, 0.0])
    _, ref, _ = nominal
    diff = rms(data["ACC_W1L_Z"] - ref["ACC_W1L_Z"])
    assert diff > 20 * truth["runs"][0]["daq"]["ACC_W1L_Z"]["lsb_g"]  # far above the quantisation step
    assert_untouched(truth, data, ref, {"ACC_W1L_Z"})


def test_wheel_polygon_shows_at_its_order(nominal):
    truth, data, pos = load("wheel_polygon")
    poly = truth["wheels"]["polygon"]
    assert poly["wheel"] == 0 and poly["order"] == 12
    _, ref, _ = nominal
    r = np.mean(truth["wheels"]["true_radius_m"][:2])  # the axle turns at its wheels' mean radius
    d = (data["ACC_W1L_Z"] - ref["ACC_W1L_Z"])
    # resample the difference to the wheel's rolling angle: the polygon is a line at its order
    angle = (pos["ws1_chainage_m"].to_numpy() - pos["ws1_chainage_m"].iloc[0]) / r
    grid = np.arange(angle[0], angle[-1], 2 * np.pi / 256)
    z = np.interp(grid, angle, d)
    spec = np.abs(np.fft.rfft(z * np.hanning(z.size)))
    orders = np.fft.rfftfreq(z.size, 1 / 256)
    band = (orders > 2) & (orders < 60)
    assert orders[band][np.argmax(spec[band])] == pytest.approx(12.0, abs=0.1)
    # the same axle's other wheel shakes with it, the other wheelset (behind the suspensions) hardly
    assert rms(data["ACC_W1R_Z"] - ref["ACC_W1R_Z"]) < rms(d)
    for n in ("ACC_W2L_Z", "ACC_W2R_Z"):
        assert rms(data[n] - ref[n]) < 0.2 * rms(d)


def _local(diff, chain, lo, hi):
    sel = (chain >= lo) & (chain <= hi)
    return rms(diff[sel])


def test_trackform_change_acts_on_its_section_only(nominal):
    truth, data, pos = load("trackform_change")
    change = truth["scenario"]["support_changes"][0]
    assert (change["from_m"], change["to_m"]) == (720.0, 780.0)
    _, ref, _ = nominal
    chain = pos["chainage_m"].to_numpy()
    for n in ("ACC_W1L_Z", "ACC_W1R_Z", "ACC_W2L_Z", "ACC_W2R_Z"):
        d = data[n] - ref[n]
        inside = _local(d, chain, 725.0, 775.0)
        assert inside > 0.03 * _local(ref[n], chain, 725.0, 775.0)
        # far before the section (beyond the track model's reach) nothing differs
        assert _local(d, chain, 400.0, 650.0) < 0.01 * inside


def test_pad_defect_acts_near_590_m_on_rail_l(nominal):
    truth, data, pos = load("pad_defect")
    _, ref, _ = nominal
    chain = pos["chainage_m"].to_numpy()
    near = {n: _local(data[n] - ref[n], chain, 585.0, 597.0) for n in ACC}
    # the defective pads are under rail L: the left axleboxes of both wheelsets react more than the right ones
    assert near["ACC_W1L_Z"] > 1.2 * near["ACC_W1R_Z"] and near["ACC_W2L_Z"] > 1.2 * near["ACC_W2R_Z"]
    for n in ("ACC_W1L_Z", "ACC_W2L_Z"):
        assert _local(data[n] - ref[n], chain, 400.0, 540.0) < 0.01 * near[n]
        assert _local(data[n] - ref[n], chain, 620.0, 800.0) < 0.01 * near[n]


def test_contact_angle_changes_the_curve_only(nominal):
    truth, data, pos = load("contact_angle")
    assert truth["curving"]["gauge_narrowing_m"] == pytest.approx(3e-3)
    _, ref, _ = nominal
    chain = pos["chainage_m"].to_numpy()
    d = data["ACC_W1L_Y"] - ref["ACC_W1L_Y"]
    assert _local(d, chain, 520.0, 660.0) > 0.05 * _local(ref["ACC_W1L_Y"], chain, 520.0, 660.0)
    assert _local(d, chain, 400.0, 440.0) < 0.01 * _local(d, chain, 520.0, 660.0)


def test_two_effects_hold_both(nominal):
    truth, data, pos = load("two_effects")
    names = {c["what"] for c in truth["scenario"]["support_changes"]}
    assert len(names) == 1 and "ACC_W1L_Z" in truth["scenario"]["sensor_offsets"]
    _, ref, _ = nominal
    chain = pos["chainage_m"].to_numpy()
    d = data["ACC_W2R_Z"] - ref["ACC_W2R_Z"]
    assert _local(d, chain, 400.0, 650.0) < 0.01 * _local(d, chain, 725.0, 775.0)
    assert rms(data["ACC_W1L_Z"][chain < 650] - ref["ACC_W1L_Z"][chain < 650]) > 0
