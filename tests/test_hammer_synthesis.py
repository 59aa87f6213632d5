"""Tests of lab_data.hammer: hammer-hit synthesis against closed forms and the FRF oracle."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, signal

from lab_data.hammer import (
    ModalTruth,
    Pulse,
    add_noise,
    analytic_accelerance,
    antialias_fir,
    exponential_window,
    force_signal,
    quantise,
    synthesize_hit,
)
from lab_data.hammer import _FOH_EQUALISER

FS = 12800.0


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def _sdof_reference_fine(freq, zeta, b, pulse, h, n_fine):
    """Acceleration of one SDOF to the *analytic* half-sine on the grid n*h.

    Independent of the module: solve_ivp (tight tolerances) while the force
    acts, textbook free vibration afterwards.
    """
    w = 2.0 * np.pi * freq
    wd = w * np.sqrt(1.0 - zeta**2)
    t_s, t_e = pulse.t0, pulse.t0 + pulse.width

    def rhs(t, x):
        f = pulse.amplitude * np.sin(np.pi * (t - t_s) / pulse.width)
        return [x[1], -w * w * x[0] - 2.0 * zeta * w * x[1] + b * f]

    sol = integrate.solve_ivp(
        rhs, (t_s, t_e), [0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-20, dense_output=True
    )
    assert sol.success
    t = np.arange(n_fine) * h
    acc = np.zeros(n_fine)
    during = (t >= t_s) & (t < t_e)
    q, v = sol.sol(t[during])
    f = pulse.amplitude * np.sin(np.pi * (t[during] - t_s) / pulse.width)
    acc[during] = b * f - w * w * q - 2.0 * zeta * w * v
    q0, v0 = sol.y[:, -1]
    tau = t[t >= t_e] - t_e
    env = np.exp(-zeta * w * tau)
    q = env * (q0 * np.cos(wd * tau) + (v0 + zeta * w * q0) / wd * np.sin(wd * tau))
    v = env * (v0 * np.cos(wd * tau) - (w * q0 + zeta * v0) * w / wd * np.sin(wd * tau))
    acc[t >= t_e] = -w * w * q - 2.0 * zeta * w * v
    return acc


def _toy_truth():
    """8 light modes in 20-480 Hz, 20 modes in 0.5-5 kHz, one rigid mode, 5 channels."""
    rng = np.random.default_rng(12345)
    low_f = np.array([23.0, 61.5, 118.0, 174.2, 236.7, 305.1, 377.4, 452.9])
    low_z = np.array([1e-4, 5e-4, 2e-3, 1e-4, 5e-3, 1e-3, 3e-4, 2e-3])
    high_f = np.sort(rng.uniform(500.0, 5000.0, 20))
    high_z = rng.uniform(1e-3, 1e-2, 20)
    freqs = np.concatenate([[0.0], low_f, high_f])
    zeta = np.concatenate([[0.0], low_z, high_z])
    b = rng.normal(0.0, 0.3, freqs.size)
    c = rng.normal(0.0, 0.3, (5, freqs.size))  # mixed signs
    return ModalTruth(freqs, zeta, b, c)


def _excluded_near_minima(mag, margin_db=20.0, notch_db=10.0):
    """Mask the lines within margin_db of an antiresonance bottom.

    An antiresonance is a local minimum of |H| with a prominence of at least
    notch_db (shallow dips between two modes are not notches and are kept).
    From each bottom the mask extends while |H| keeps rising and stays below
    bottom + margin_db, so it never reaches into a resonance.
    """
    db = 20.0 * np.log10(mag)
    excl = np.zeros(mag.size, dtype=bool)
    bottoms, _ = signal.find_peaks(-db, prominence=notch_db)
    for i in bottoms:
        lim = db[i] + margin_db
        lo = i
        while lo > 0 and lim > db[lo - 1] >= db[lo]:
            lo -= 1
        hi = i
        while hi < mag.size - 1 and lim > db[hi + 1] >= db[hi]:
            hi += 1
        excl[lo : hi + 1] = True
    return excl


def _h1_errors(truth, pulses, decay, f_lo=10.0, f_hi=500.0):
    """Windowed single-hit H1 from the synthesised signals vs the oracle.

    Returns (max |dB error|, max |phase error| in degrees, fraction of lines kept).
    """
    t, force, accel = synthesize_hit(truth, pulses, fs=FS, duration=4.0)
    win = exponential_window(t.size, FS, 0.0, decay)
    fw, aw = force * win, accel * win
    # The window must have killed the response by the record end (no leakage).
    assert np.abs(aw[:, -10:]).max() < 1e-6 * np.abs(aw).max()
    spec_f = np.fft.rfft(fw)
    spec_a = np.fft.rfft(aw, axis=1)
    freqs = np.fft.rfftfreq(t.size, 1.0 / FS)
    h1 = np.conj(spec_f) * spec_a / (np.abs(spec_f) ** 2)
    wide = (freqs >= f_lo - 5.0) & (freqs <= f_hi + 20.0)
    h_true = analytic_accelerance(truth, freqs[wide], decay=decay)
    band = (freqs[wide] >= f_lo) & (freqs[wide] <= f_hi)
    db_err, ph_err, kept = [], [], []
    for j in range(truth.n_outputs):
        mag = np.abs(h_true[j])
        keep = band & ~_excluded_near_minima(mag)
        ratio = h1[j, wide][keep] / h_true[j][keep]
        db_err.append(np.abs(20.0 * np.log10(np.abs(ratio))).max())
        ph_err.append(np.abs(np.degrees(np.angle(ratio))).max())
        kept.append(keep.sum() / band.sum())
    return max(db_err), max(ph_err), min(kept)


# --------------------------------------------------------------------------
# 1. SDOF against an independent closed-form / ODE reference
# --------------------------------------------------------------------------
def test_sdof_half_sine_matches_independent_reference():
    freq, zeta, b, c = 180.0, 0.01, 0.7, 1.3
    pulse = Pulse(t0=0.05, width=5e-4, amplitude=200.0)
    # The response follows the fine *samples* of the half-sine, whose spectrum
    # contains the aliases of the analytic one: O((pi h / width)**2), ~1e-3
    # at oversample=4 (common to force and response, so harmless for FRFs,
    # see the H1 tests) and ~1e-5 of the peak here at oversample=16.
    os_, duration = 16, 0.5
    truth = ModalTruth([freq], [zeta], [b], [[c]])
    t, force, accel = synthesize_hit(truth, pulse, fs=FS, duration=duration, oversample=os_)
    accel = accel[0]
    n = t.size
    h = 1.0 / (FS * os_)
    taps = antialias_fir(os_)
    pad = taps.size  # continue the reference past the record end: no end transient
    ref_fine = c * _sdof_reference_fine(freq, zeta, b, pulse, h, n * os_ + pad)
    ref = signal.resample_poly(ref_fine, 1, os_, window=taps)[:n]
    peak = np.abs(ref).max()
    assert peak > 0.5 * abs(c * b * pulse.amplitude)  # the pulse itself dominates the peak
    np.testing.assert_array_less(np.abs(accel - ref), 1e-4 * peak)

    # Free vibration (filter support clear of the pulse): the band-limited
    # record equals the unfiltered closed form, i.e. the pass band is flat.
    free = t > pulse.t0 + pulse.width + taps.size / (FS * os_)
    unfiltered = ref_fine[: n * os_ : os_]
    np.testing.assert_array_less(np.abs(accel[free] - unfiltered[free]), 1e-4 * peak)

    # The force channel is the same filter applied to the analytic half-sine.
    ref_force = signal.resample_poly(
        force_signal(np.arange(n * os_ + pad) * h, pulse), 1, os_, window=taps
    )[:n]
    np.testing.assert_allclose(force, ref_force, rtol=0.0, atol=1e-12 * pulse.amplitude)


def test_fast_path_equals_brute_force_foh_lfilter_resample_poly():
    """The closed-form continuation reproduces the textbook route to round-off:
    cont2discrete(foh) + lfilter on the full fine grid (modal input through the
    sinc**-2 equaliser, direct term on the plain samples), then resample_poly."""
    rng = np.random.default_rng(7)
    m = 25
    freqs = np.concatenate([[0.0], rng.uniform(15.0, 6000.0, m - 1)])
    zeta = rng.uniform(1e-4, 2e-2, m)
    truth = ModalTruth(freqs, zeta, rng.normal(size=m), rng.normal(size=(3, m)))
    pulses = [Pulse(0.1, 5e-4, 100.0), Pulse(0.104, 5e-4, 40.0), Pulse(0.7, 8e-4, -30.0)]
    os_, duration = 4, 1.0
    t, force, accel = synthesize_hit(truth, pulses, fs=FS, duration=duration, oversample=os_)

    h = 1.0 / (FS * os_)
    u = force_signal(np.arange(t.size * os_) * h, pulses)
    u_eq = np.convolve(u, _FOH_EQUALISER, mode="same")
    fine = np.zeros((truth.n_outputs, u.size))
    for r in range(m):
        w, z, b = 2 * np.pi * freqs[r], zeta[r], truth.input_shape[r]
        if w == 0.0:
            y = b * u
        else:
            a_c = np.array([[0.0, 1.0], [-w * w, -2 * z * w]])
            sysd = signal.cont2discrete(
                (a_c, np.array([[0.0], [b]]), np.array([[-w * w, -2 * z * w]]), np.array([[b]])),
                h,
                method="foh",
            )
            num, den = signal.ss2tf(*sysd[:4])
            # lfilter gives b*u_eq + C x[u_eq]; swap the feed-through to b*u.
            y = signal.lfilter(num[0], den, u_eq) + b * (u - u_eq)
        fine += np.outer(truth.output_shapes[:, r], y)
    taps = antialias_fir(os_)
    ref = signal.resample_poly(fine, 1, os_, axis=1, window=taps)
    ref_force = signal.resample_poly(u, 1, os_, window=taps)
    # resample_poly zero-pads past the end; our front-end keeps running.
    tail = taps.size // os_ + 2
    peak = np.abs(ref).max()
    np.testing.assert_array_less(np.abs(accel - ref)[:, :-tail], 1e-9 * peak)
    np.testing.assert_allclose(force, ref_force, rtol=0.0, atol=1e-12 * 100.0)


def test_foh_equaliser_inverts_interpolation_kernel():
    """c(f) * sinc**2(pi f h) = 1 in the analysed band (the FOH input equaliser)."""
    assert _FOH_EQUALISER.size == 7
    np.testing.assert_allclose(_FOH_EQUALISER, _FOH_EQUALISER[::-1], atol=0.0)
    for os_, tol in ((4, 1e-5), (8, 1e-7)):
        f = np.linspace(0.0, 0.4 * FS, 500)
        _, resp = signal.freqz(_FOH_EQUALISER, worN=f, fs=FS * os_)
        gain = np.abs(resp) * np.sinc(f / (FS * os_)) ** 2
        np.testing.assert_allclose(gain, 1.0, rtol=0.0, atol=tol)


def test_antialias_fir_flat_passband_and_deep_stopband():
    for os_ in (2, 4, 8):
        taps = antialias_fir(os_)
        assert taps.size % 2 == 1
        np.testing.assert_allclose(taps, taps[::-1], atol=0.0)  # zero phase
        freqs, resp = signal.freqz(taps, worN=2**16, fs=FS * os_)
        mag = np.abs(resp)
        assert np.abs(mag[freqs <= 0.4 * FS] - 1.0).max() < 1e-4
        assert 20 * np.log10(mag[freqs >= 0.6 * FS].max()) < -80.0
    np.testing.assert_array_equal(antialias_fir(1), [1.0])


# --------------------------------------------------------------------------
# 2. Key acceptance: windowed H1 from the synthesised record == oracle
# --------------------------------------------------------------------------
DECAY = 4.0  # 1/s: exp(-4 * 3.9 s) = 1.7e-7 at the record end

SCENARIOS = {
    "single_0p5ms": [Pulse(0.1, 5e-4, 150.0)],
    "double_hit": [Pulse(0.1, 5e-4, 150.0), Pulse(0.104, 5e-4, 60.0)],
    "single_1ms": [Pulse(0.1, 1e-3, 150.0)],
}


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_windowed_h1_matches_analytic_accelerance(name):
    truth = _toy_truth()
    db_err, ph_err, kept = _h1_errors(truth, SCENARIOS[name], DECAY)
    assert kept > 0.5  # the antiresonance exclusion leaves most of the band
    assert db_err < 0.02, f"{name}: max magnitude error {db_err:.4f} dB"
    assert ph_err < 0.2, f"{name}: max phase error {ph_err:.4f} deg"


def test_windowed_h1_matches_up_to_0p4_fs():
    """Also above the light modes, up to 0.4 fs (this is what the FOH input
    equaliser is for: without it the error reaches ~0.8 dB near 2 kHz)."""
    truth = _toy_truth()
    db_err, ph_err, kept = _h1_errors(
        truth, SCENARIOS["single_0p5ms"], DECAY, f_lo=500.0, f_hi=0.4 * FS - 25.0
    )
    assert kept > 0.3  # 20 modes here: many antiresonances
    assert db_err < 0.02, f"max magnitude error {db_err:.4f} dB"
    assert ph_err < 0.2, f"max phase error {ph_err:.4f} deg"


def test_force_signal_half_sines():
    pulses = [Pulse(0.01, 1e-3, 10.0), Pulse(0.0105, 1e-3, 4.0)]
    t = np.array([0.0, 0.01, 0.0105, 0.011, 0.01149, 0.0115, 0.02])
    f = force_signal(t, pulses)
    expected = [0.0, 0.0, 10.0, 4.0, 4.0 * np.sin(np.pi * 0.99e-3 / 1e-3), 0.0, 0.0]
    # at t = 0.011 the first pulse ends (half-open) and the second peaks
    np.testing.assert_allclose(f, expected, atol=1e-9)


def test_h1_check_detects_a_wrong_truth():
    """The acceptance comparison is sharp: 1 % frequency shift of one mode fails it."""
    truth = _toy_truth()
    freqs = truth.freqs_hz.copy()
    freqs[4] *= 1.01  # 174 Hz mode
    wrong = ModalTruth(freqs, truth.zeta, truth.input_shape, truth.output_shapes)
    t, force, accel = synthesize_hit(truth, SCENARIOS["single_0p5ms"], fs=FS, duration=4.0)
    win = exponential_window(t.size, FS, 0.0, DECAY)
    freq_axis = np.fft.rfftfreq(t.size, 1.0 / FS)
    sel = (freq_axis > 150) & (freq_axis < 200)
    h1 = np.fft.rfft(accel * win, axis=1)[:, sel] / np.fft.rfft(force * win)[sel]
    err = np.abs(20 * np.log10(np.abs(h1 / analytic_accelerance(wrong, freq_axis[sel], DECAY))))
    assert err.max() > 1.0


# --------------------------------------------------------------------------
# 3. Why the lab needs an exponential window
# --------------------------------------------------------------------------
def test_light_mode_rings_to_end_of_record_without_window():
    truth = ModalTruth([425.0], [1e-4], [0.5], [[1.0]])
    t, _, accel = synthesize_hit(truth, Pulse(0.1, 5e-4, 100.0), fs=FS, duration=4.0)
    a = accel[0]
    early = np.abs(a[(t > 0.2) & (t < 0.3)]).max()
    late = np.abs(a[t > 3.9]).max()
    assert late > 0.1 * early  # exp(-1e-4 * 2 pi 425 * 3.7) = 0.37
    # ... and the window makes it vanish.
    win = exponential_window(t.size, FS, 0.0, DECAY)
    assert np.abs((a * win)[t > 3.9]).max() < 1e-6 * early


# --------------------------------------------------------------------------
# 4. ADC and noise
# --------------------------------------------------------------------------
def test_quantise_step_and_clipping_exact():
    fs_range, bits = 2.0, 8
    step = 2 * fs_range / 2**bits
    x = np.array([0.0, 0.3 * step, 0.51 * step, -1.49 * step, 1.99, 2.0, 2.0001, -5.0, 1e9])
    q, mask = quantise(x, fs_range, bits=bits)
    np.testing.assert_array_equal(mask, [False] * 6 + [True] * 3)
    np.testing.assert_array_equal(q[mask], [2.0, -2.0, 2.0])  # saturates flat
    np.testing.assert_array_equal(q[:4], [0.0, 0.0, step, -step])
    # every output is an integer number of steps, within half a step if not clipped
    np.testing.assert_array_equal(q / step, np.round(q / step))
    assert np.all(np.abs(q[~mask] - x[~mask]) <= step / 2)
    assert x[0] == 0.0 and x[-1] == 1e9  # input untouched


def test_quantise_24_bit_per_channel_ranges():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(2, 1000)) * np.array([[1.0], [50.0]])
    ranges = np.array([10.0, 20.0])
    q, mask = quantise(x, ranges)
    np.testing.assert_array_equal(mask, np.abs(x) > ranges[:, None])
    assert not mask[0].any() and mask[1].any()
    half_step = (2 * ranges / 2**24 / 2)[:, None] * np.ones_like(x)
    assert np.all(np.abs(q - x)[~mask] <= half_step[~mask])
    np.testing.assert_array_equal(np.abs(q[1][mask[1]]), 20.0)


def test_add_noise_statistics_and_purity():
    rng = np.random.default_rng(11)
    clean = np.zeros((2, 200_000))
    noisy = add_noise(clean, np.array([0.1, 2.0]), rng)
    assert clean.max() == 0.0  # new array, input untouched
    np.testing.assert_allclose(noisy.std(axis=1), [0.1, 2.0], rtol=0.01)
    again = add_noise(clean, np.array([0.1, 2.0]), np.random.default_rng(11))
    np.testing.assert_array_equal(noisy, again)


# --------------------------------------------------------------------------
# 5. Validation
# --------------------------------------------------------------------------
def _ok_truth(**over):
    kw = dict(freqs_hz=[0.0, 100.0], zeta=[0.0, 0.01], input_shape=[1.0, 0.5],
              output_shapes=[[1.0, -0.3]])
    kw.update(over)
    return ModalTruth(**kw)


@pytest.mark.parametrize(
    "over, field",
    [
        (dict(freqs_hz=[-1.0, 100.0]), "freqs_hz"),
        (dict(freqs_hz=[np.nan, 100.0]), "freqs_hz"),
        (dict(zeta=[0.0, 1.0]), "zeta"),
        (dict(zeta=[-0.1, 0.01]), "zeta"),
        (dict(zeta=[0.01]), "zeta"),
        (dict(input_shape=[1.0, 2.0, 3.0]), "input_shape"),
        (dict(output_shapes=[[1.0, 2.0, 3.0]]), "output_shapes"),
        (dict(output_shapes=[1.0, 2.0]), "output_shapes"),
    ],
)
def test_modal_truth_validation(over, field):
    with pytest.raises(ValueError, match=field):
        _ok_truth(**over)


def test_modal_truth_message_contains_value_and_is_read_only():
    with pytest.raises(ValueError, match=r"freqs_hz.*-7\.5"):
        _ok_truth(freqs_hz=[-7.5, 100.0])
    truth = _ok_truth()
    with pytest.raises(ValueError):
        truth.freqs_hz[0] = 3.0  # read-only array


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(t0=0.1, width=0.0, amplitude=1.0), "width"),
        (dict(t0=0.1, width=-1e-4, amplitude=1.0), "width"),
        (dict(t0=-0.1, width=5e-4, amplitude=1.0), "t0"),
        (dict(t0=0.1, width=5e-4, amplitude=np.inf), "amplitude"),
    ],
)
def test_pulse_validation(kwargs, field):
    with pytest.raises(ValueError, match=field):
        Pulse(**kwargs)


def test_pulse_outside_record_rejected():
    truth = _ok_truth()
    with pytest.raises(ValueError, match=r"t0 = 5\.0"):
        synthesize_hit(truth, Pulse(5.0, 5e-4, 1.0), duration=4.0)
    with pytest.raises(ValueError, match="t0.*width"):
        synthesize_hit(truth, Pulse(3.9998, 5e-4, 1.0), duration=4.0)
    with pytest.raises(ValueError, match="width"):
        synthesize_hit(truth, Pulse(0.1, 1e-5, 1.0))  # not resolved by the fine grid
    with pytest.raises(ValueError, match="oversample"):
        synthesize_hit(truth, Pulse(0.1, 5e-4, 1.0), oversample=2.5)


def test_analytic_accelerance_limits():
    truth = _ok_truth()
    h = analytic_accelerance(truth, [0.0, 1e7])
    assert np.all(np.isfinite(h))
    # f = 0: only the rigid mode; f -> inf: sum of c b (mass line)
    np.testing.assert_allclose(h[0, 0], 1.0, rtol=1e-12)
    np.testing.assert_allclose(h[0, 1], 1.0 - 0.15, rtol=1e-6)
    with pytest.raises(ValueError, match="decay"):
        analytic_accelerance(truth, [1.0], decay=-1.0)
