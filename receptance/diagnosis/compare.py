"""Model against measurement: compare, and localise where the model fails (thesis Figs. 3.18–3.19).

The model's accelerance at the test's sensors (driven at the test's force
channel, seen through the measurement's exponential window so both have the
same pole shift) is set beside the measured H1 (thesis eq. 3.2) of one or
more hammer setups, on the same frequency lines. ``H_x`` is measured,
``H_m`` the model, ``c`` a channel (one sensor in one setup), ``f`` a line.

Per channel over the whole band (kept from the first version):

* ``db_rms``: RMS over the band of ``20 log10(|H_m| / |H_x|)`` [dB] — how far
  apart the curves look on the usual log plot (antiresonances weigh a lot);
* ``rel_error``: ``‖H_m − H_x‖₂ / ‖H_x‖₂`` over the band — the complex
  (magnitude and phase) misfit, dominated by the strongest resonances;
* ``frac``: frequency response assurance criterion
  ``|Σ H_x* H_m|² / (Σ|H_x|² Σ|H_m|²)`` (1 = same shape over frequency).

Band-normalised complex error
    The band is split into bands ``b`` (default: octaves from the lower band
    edge, e.g. 10–20–40–80–160–320–500 Hz, see :func:`octave_bands`). For every
    channel and band::

        e_cb = ‖H_m − H_x‖_b / ‖H_x‖_b        (2-norms over the lines of band b)

    Normalising per channel *and* per band makes a misfit of the mass line at
    10–40 Hz count as much as a misfit at a strong resonance near 300 Hz (the
    accelerance grows roughly like f² so a global norm would only see the top
    octave), and makes weak channels count as much as strong ones.

Figure of merit (``Comparison.summary``)
    The RMS over channels and bands of the band-normalised complex error::

        E = sqrt( mean_{c,b} e_cb² )

    dimensionless (0.05 = 5 %); 0 for a perfect model on noise-free data.
    Because ``E²`` is a mean of per-line terms
    ``w_cf = |H_m − H_x|²_cf / ‖H_x‖²_{c,b(f)}`` it splits exactly into the
    *share* of the error carried by each channel, band, body or frequency
    window (peak): ``share = Σ w over the part / Σ w over everything``. The
    rankings of :attr:`Comparison.ranking` use these shares.

    Why this figure: it is dimensionless, weighs every octave and every sensor
    alike, sees phase as well as magnitude, decomposes exactly into shares,
    and has a computable noise floor. Its price: it averages over bands whose
    floors differ by orders of magnitude (virtual-lab control: 14 % and 11 % at
    10–20 and 20–40 Hz, where the mass-line response is weak, 0.2–3 % above),
    so a misfit confined to one band moves ``E`` far less than that band's own
    error — read :attr:`Comparison.bands` (error beside floor) with it; a 1 %
    frequency error on the strongest mode doubles ``E`` on the lab's control
    campaign but is 100× the floor of its band.

    ``summary_db`` (median over channels of ``db_rms``) is kept for display
    and backwards compatibility; it is *not* the figure of merit (noise at the
    antiresonances dominates it).

Noise floor (``Comparison.noise_floor``)
    What a perfect model would score against this noisy measurement. The random
    error of an H1 estimate averaged over ``n`` hits (Bendat & Piersol, *Random
    Data*, ch. 9, random errors of gain and phase estimates) has normalised
    standard deviation ``ε = σ|H|/|H| ≈ sqrt((1 − γ²) / (2 n γ²))`` in
    magnitude and the same ``ε`` (in rad) in phase, so the expected squared
    complex error of the line is ``σ²_cf = 2 ε² |H|² = |H_x|² (1 − γ²) / (n γ²)``.
    Here ``n`` is replaced by ``n − 1``: ``S_aa − |S_fa|²/S_ff`` is the residual
    power of a one-complex-parameter fit to ``n`` hits and estimates
    ``(n − 1)/n`` of the noise power, so with ``n − 1`` the expectation is exact,
    ``E|Ĥ₁ − H|² = σ²_noise / Σ_k |F_k|²`` (tests/test_compare.py checks it by
    Monte Carlo; with ``n`` the floor would be 20 % low in ``E²`` for 5 hits).
    Then::

        floor_cb² = Σ_{f∈b} σ²_cf / ‖H_x‖²_b ,   noise_floor = sqrt( mean_{c,b} floor_cb² )

    A model equal to the truth scores ``E ≈ noise_floor`` (in expectation);
    ``E / noise_floor`` says how far a model is from being as good as the data
    allow. The floor needs the coherence and the number of averages of the
    measured FRF (``ema.estimate_frf`` supplies both); with a single hit
    (``n = 1``, coherence identically 1) or without them it is NaN.

Where it fails: shares above the noise floor
    Noise is not a model failure. Each channel×band cell's error above the
    floor is ``x_cb = max(e_cb² − floor_cb², 0)``; the *excess share* of a
    channel, band, body or peak window is its part of ``Σ x``. The rankings
    (:attr:`Comparison.ranking`, :meth:`Comparison.where`) order by excess
    share when the floor is known, by plain share otherwise; both are reported.

Peaks (``Comparison.peaks``)
    A resonance shows as a peak on many channels at once. Every channel's
    ``20 log10 |H|`` is searched for local maxima with a topographic
    prominence of at least ``peak_prominence_db`` (default 3 dB;
    ``scipy.signal.find_peaks``), each refined by a parabola through the three
    lines around it. On the measurement a channel peak counts only where the
    line's random error ``ε = σ/(√2 |H_x|)`` is at most 0.05 (0.4 dB): the
    noise that fills a deep antiresonance makes local maxima of any
    prominence, a resonance is where the response stands far above the noise
    (its coherence there is > 0.99 on a hammer test). Channel peaks are
    grouped around the densest frequencies (:func:`cluster_peaks`, window
    ``±max(1 line, 0.25 % f)``); a group seen on at least
    ``peak_min_channels`` distinct channels (default ``max(4, ⌈n/10⌉)``) is a
    resonance at the median frequency of the group — fewer channels are local
    maxima between two antiresonances, not modes. (A sum over channels of
    ``|H|²``, the single-reference CMIF, misses a weak, well-damped mode on the
    skirt of a strong one — the 2 %-damped absorber of the virtual lab next to
    the 3rd bending mode — which the channel-by-channel search finds on 20
    channels.) Measured and model resonances are matched one to one
    (Hungarian assignment on ``|Δf|/f``) when within ``peak_tolerance``
    (default 3 %). Unmatched measured peaks are *modes present in the
    measurement but not in the model*; unmatched model peaks the converse.
    Each peak owns the window ``±peak_tolerance/2`` around it (clipped half
    way to the next peak); its share of the error is that of the lines in the
    window. ``indicator_measured``/``indicator_model`` (the channel-normalised
    mean power ``P(f) = mean_c |H_cf|² / mean_{f'} |H_x,cf'|²``) are kept for
    plotting the peaks.

Bodies
    Each channel belongs to a body — ``axle``, ``wheel``, ``disc``, ``axlebox``
    or ``other`` — given by the caller (``bodies=``, a mapping by channel name
    or row key, or a callable on the name), else by a ``body`` column of the
    channel table, else by its name (:func:`infer_body`: a name starting with ``axlebox`` → axlebox,
    ``axle`` → axle, ``wheel`` → wheel, ``disc``/``disk``/``brake`` → disc,
    anything else → other). The side (``L``/``R``) comes from the name
    (``wheelL_3``, ``discR_2``, ``axleboxL_z``, ``disc_L``) or else from the
    sign of ``y`` (left at −y, DESIGN.md); ``part`` is ``body_side`` for
    wheels, discs and axleboxes (e.g. ``disc_L``) and the body otherwise.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment
from scipy.signal import find_peaks

from ema.frf import FrequencyResponse
from ema._blas import one_blas_thread
from receptance.modal_model import ModalModel, ModelError

__all__ = ["Comparison", "ComparisonError", "compare", "compare_frf", "frf_errors", "infer_body", "infer_side",
           "octave_bands", "band_errors", "channel_peaks", "cluster_peaks", "h1_variance", "BODIES"]

log = logging.getLogger("receptance")

#: body labels, in the order plots group them
BODIES = ("axle", "wheel", "disc", "axlebox", "other")
_SIDED = {"wheel", "disc", "axlebox"}
_BODY_RULES = (("axlebox", "axlebox"), ("axle", "axle"), ("wheel", "wheel"), ("disc", "disc"), ("disk", "disc"),
               ("brake", "disc"))


class ComparisonError(ModelError):
    """Measured and model responses that cannot be compared (names the setup, channel or parameter)."""


# --------------------------------------------------------------------------- helpers
def frf_errors(measured: np.ndarray, model: np.ndarray) -> dict[str, np.ndarray]:
    """Per-row ``db_rms``, ``rel_error`` and ``frac`` of two complex arrays ``(n_channels, n_freq)``."""
    Hx = np.asarray(measured, complex)
    Hm = np.asarray(model, complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio_db = 20 * np.log10(np.abs(Hm) / np.abs(Hx))
    ratio_db = np.where(np.isfinite(ratio_db), ratio_db, np.nan)
    db_rms = np.sqrt(np.nanmean(ratio_db**2, axis=1))
    rel = np.linalg.norm(Hm - Hx, axis=1) / np.linalg.norm(Hx, axis=1)
    frac = np.abs(np.sum(Hx.conj() * Hm, axis=1)) ** 2 / (np.sum(np.abs(Hx) ** 2, axis=1)
                                                         * np.sum(np.abs(Hm) ** 2, axis=1))
    return {"db_rms": db_rms, "rel_error": rel, "frac": frac}


def octave_bands(band_hz: tuple[float, float]) -> tuple[tuple[float, float], ...]:
    """Octave bands from the lower edge of ``band_hz`` up to its upper edge.

    Edges ``lo, 2 lo, 4 lo, ...`` while below ``hi``; the last band ends at
    ``hi``. A last band narrower than half an octave (``hi / edge < √2``) is
    merged into the one below. ``(10, 500)`` gives 10–20–40–80–160–320–500 Hz.
    """
    lo, hi = float(band_hz[0]), float(band_hz[1])
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo <= 0 or hi <= lo:
        raise ComparisonError(f"band_hz must be (low, high) with 0 < low < high, got {band_hz!r}")
    edges = [lo]
    while edges[-1] * 2 < hi:
        edges.append(edges[-1] * 2)
    if len(edges) > 1 and hi / edges[-1] < np.sqrt(2):
        edges.pop()
    edges.append(hi)
    return tuple((edges[k], edges[k + 1]) for k in range(len(edges) - 1))


def band_errors(freqs_hz: np.ndarray, measured: np.ndarray, model: np.ndarray,
                bands_hz: Sequence[tuple[float, float]]) -> np.ndarray:
    """Band-normalised complex errors ``e_cb`` of two ``(n_channels, n_freq)`` arrays (module docstring).

    The cheap core of :class:`Comparison` for fitting loops: the figure of
    merit of a candidate model is ``sqrt(mean(band_errors(...)**2))`` with the
    comparison's ``bands_hz`` and stacked ``measured.data[:, 0]``.

    Returns
    -------
    ndarray (n_channels, n_bands)
    """
    f = np.asarray(freqs_hz, float)
    Hx, Hm = np.asarray(measured), np.asarray(model)
    out = np.empty((Hx.shape[0], len(bands_hz)))
    last = bands_hz[-1][1]
    for b, (lo, hi) in enumerate(bands_hz):
        sel = (f >= lo) & ((f <= hi) if hi >= last else (f < hi))
        if not sel.any():
            raise ComparisonError(f"band {_band_label(lo, hi)} holds no frequency line")
        out[:, b] = np.sqrt(np.sum(np.abs(Hm[:, sel] - Hx[:, sel]) ** 2, axis=1)
                            / np.sum(np.abs(Hx[:, sel]) ** 2, axis=1))
    return out


def _band_label(lo: float, hi: float) -> str:
    return f"{lo:g}–{hi:g} Hz"


def infer_body(name: str) -> str:
    """Body of a channel from its name (module docstring): axle, wheel, disc, axlebox or other."""
    n = str(name).strip().lower()
    for prefix, body in _BODY_RULES:
        if n.startswith(prefix):
            return body
    return "other"


def infer_side(name: str, y: float | None = None) -> str:
    """``"L"``, ``"R"`` or ``""``: from the name (``wheelL_3``, ``disc_R``, ``axleboxL_z``), else from the sign of y.

    Left is at −y (DESIGN.md); a ``y`` within 1 µm of 0 has no side.
    """
    m = re.match(r"^(?:axlebox|wheel|disc|disk|brake)[_\- ]?([LR])(?:[_\- ]|$)", str(name).strip(), re.IGNORECASE)
    if m:
        return m.group(1).upper()
    if y is not None and np.isfinite(y) and abs(y) > 1e-6:
        return "L" if y < 0 else "R"
    return ""


def _part(body: str, side: str) -> str:
    return f"{body}_{side}" if body in _SIDED and side else body


# --------------------------------------------------------------------------- the result
@dataclass(frozen=True, eq=False)
class Comparison:
    """Measured and model FRFs on the same lines, with errors per channel, band, body and peak.

    Built by :func:`compare` (or :func:`compare_frf`); the attributes after
    ``measurements`` are computed on construction from the two responses
    (module docstring for the definitions), so a Comparison built directly
    from two FrequencyResponses is complete too.

    Parameters
    ----------
    measured, model : FrequencyResponse
        Accelerance, same outputs (row keys, see ``channels['key']``), one
        input, same frequency lines. Several setups are stacked along the
        outputs.
    channels : pandas.DataFrame
        One row per output, at least ``channel`` (the sensor name). Columns
        ``key``, ``setup``, ``body``, ``side``, ``part`` are added when missing.
    band_hz : (float, float)
    summary_db : float, optional
        Median over channels of ``db_rms`` (computed when not given).
    bands_hz : sequence of (float, float), optional
        Bands of the band-normalised error; default :func:`octave_bands`.
    peak_prominence_db, peak_tolerance : float
        Peak detection and matching rules (module docstring).
    peak_min_channels : int, optional
        Channels that must show a peak for it to be a resonance; default
        ``max(4, ceil(n_channels / 10))`` (stored resolved).
    measurements : tuple
        The ``(setup, FrequencyResponse, channel table)`` triples compared
        (as given to :func:`compare`, band not applied), so the same
        measurement can be compared with another model:
        ``compare(other_model, comparison.measurements)``.
    noise_variance : ndarray (n_out, n_freq), optional
        Expected squared random error of each measured line, used for the
        noise floor when the measured FRF has no coherence and averaging
        count (an FRF file without coherence,
        :func:`receptance.diagnosis.noise.frf_noise_variance`).

    Attributes
    ----------
    channels : pandas.DataFrame
        Per channel: ``key, channel, setup, body, side, part, db_rms, rel_error,
        frac, band_error`` (RMS over bands of ``e_cb``), ``floor`` (same for
        the noise floor), ``excess`` (RMS of ``x_cb``, the error above the
        floor), ``share`` (of ``E²``), ``excess_share`` (of ``Σ x``), and the
        channel table's ``node, x, y, z, dx, dy, dz, fe_node`` and the
        measurement's ``n_averages, exp_window_decay`` when known.
    summary : float
        The figure of merit ``E`` (module docstring).
    noise_floor : float
        ``E`` of a perfect model on this measurement (NaN without coherence
        or with single hits).
    bands : pandas.DataFrame
        Per band: ``band, lo_hz, hi_hz, n_lines, error`` (RMS over channels of
        ``e_cb``), ``floor``, ``excess``, ``share``, ``excess_share``.
    band_errors, band_floors : pandas.DataFrame
        ``e_cb`` and ``floor_cb``: rows = channel keys, columns = band labels.
    body_band_errors : pandas.DataFrame
        RMS over a body's channels of ``e_cb``: rows = bodies, columns = bands.
    bodies : pandas.DataFrame
        Per body: ``body, n_channels, error, floor, excess, share,
        excess_share``; ``parts`` the same per ``part`` (``disc_L``...).
    error_map_db : ndarray (n_channels, n_freq)
        ``20 log10 |H_m / H_x|`` (NaN where either is zero).
    line_share : ndarray (n_channels, n_freq)
        Share of ``E²`` carried by each channel and line (0 outside the bands).
    indicator_measured, indicator_model : ndarray (n_freq,)
        Channel-normalised mean power ``P(f)`` (for plots of the peaks).
    peaks : pandas.DataFrame
        One row per resonance, by frequency: ``status`` (``matched`` /
        ``measured only`` / ``model only``), ``f_measured_hz, f_model_hz,
        shift_hz, shift_pct`` (model − measured), ``n_channels_measured,
        n_channels_model`` (channels showing it), ``prominence_measured_db,
        prominence_model_db`` (largest channel prominence), ``lo_hz, hi_hz``
        (its window), ``error`` (band-normalised complex error over the window,
        RMS over channels), ``share``, ``excess_share``.
    ranking : pandas.DataFrame
        Where it fails: ``kind`` (channel, band, body, part, peak), ``name``,
        ``share``, ``excess_share``, ``error``, ``rank`` (1 = largest excess
        share within the kind, or share when the floor is unknown); see
        :meth:`where`.
    """

    measured: FrequencyResponse
    model: FrequencyResponse
    channels: pd.DataFrame = field(repr=False)
    band_hz: tuple[float, float]
    summary_db: float | None = None
    bands_hz: tuple[tuple[float, float], ...] | None = None
    peak_prominence_db: float = 3.0
    peak_tolerance: float = 0.03
    peak_min_channels: int | None = None
    measurements: tuple = field(default=(), repr=False)
    noise_variance: np.ndarray | None = field(default=None, repr=False)

    summary: float = field(init=False)
    noise_floor: float = field(init=False)
    bands: pd.DataFrame = field(init=False, repr=False)
    band_errors: pd.DataFrame = field(init=False, repr=False)
    band_floors: pd.DataFrame = field(init=False, repr=False)
    body_band_errors: pd.DataFrame = field(init=False, repr=False)
    bodies: pd.DataFrame = field(init=False, repr=False)
    parts: pd.DataFrame = field(init=False, repr=False)
    error_map_db: np.ndarray = field(init=False, repr=False)
    line_share: np.ndarray = field(init=False, repr=False)
    indicator_measured: np.ndarray = field(init=False, repr=False)
    indicator_model: np.ndarray = field(init=False, repr=False)
    peaks: pd.DataFrame = field(init=False, repr=False)
    ranking: pd.DataFrame = field(init=False, repr=False)

    # ------------------------------------------------------------------ construction
    def __post_init__(self) -> None:
        mx, mm = self.measured, self.model
        if mx.outputs != mm.outputs or mx.n_in != 1 or mm.n_in != 1:
            raise ComparisonError(f"measured and model must have the same outputs and one input; got "
                                  f"{mx.n_out}x{mx.n_in} and {mm.n_out}x{mm.n_in} (outputs equal: "
                                  f"{mx.outputs == mm.outputs})")
        if mx.freqs_hz.shape != mm.freqs_hz.shape or not np.allclose(mx.freqs_hz, mm.freqs_hz, rtol=1e-9, atol=0):
            raise ComparisonError("measured and model must share their frequency lines")
        if len(self.channels) != mx.n_out:
            raise ComparisonError(f"channels has {len(self.channels)} rows for {mx.n_out} outputs")
        n_min = self.peak_min_channels
        if n_min is None:
            n_min = max(4, int(np.ceil(mx.n_out / 10)))
        if not (0 < self.peak_tolerance < 1) or not self.peak_prominence_db > 0 or n_min < 1:
            raise ComparisonError(f"peak_tolerance must lie in (0, 1), peak_prominence_db be > 0 and "
                                  f"peak_min_channels >= 1; got {self.peak_tolerance!r}, "
                                  f"{self.peak_prominence_db!r}, {self.peak_min_channels!r}")
        f = mx.freqs_hz
        band = (float(self.band_hz[0]), float(self.band_hz[1]))
        bands = tuple((float(a), float(b)) for a, b in (self.bands_hz or octave_bands(band)))
        Hx, Hm = mx.data[:, 0], mm.data[:, 0]
        table = _complete_table(self.channels.reset_index(drop=True), mx.outputs)

        err = frf_errors(Hx, Hm)
        for k, v in err.items():
            table[k] = v
        summary_db = float(np.median(err["db_rms"])) if self.summary_db is None else float(self.summary_db)

        # per-line weights w_cf and noise terms phi_cf, band by band (module docstring)
        labels, members = [], []
        for lo, hi in bands:
            last = hi >= bands[-1][1]
            sel = (f >= lo) & ((f <= hi) if last else (f < hi))
            if not sel.any():
                raise ComparisonError(f"band {_band_label(lo, hi)} holds no frequency line of the measurement "
                                      f"({f[0]:g}–{f[-1]:g} Hz, {f.size} lines); choose wider bands")
            labels.append(_band_label(lo, hi))
            members.append(sel)
        sigma2 = h1_variance(mx)
        if sigma2 is None and self.noise_variance is not None:
            sigma2 = np.asarray(self.noise_variance, float)
            if sigma2.shape != Hx.shape:
                raise ComparisonError(f"noise_variance has shape {sigma2.shape}, the measurement {Hx.shape}")
        d2 = np.abs(Hm - Hx) ** 2
        w = np.zeros_like(d2)
        phi = np.full_like(d2, np.nan) if sigma2 is None else np.zeros_like(d2)
        e2 = np.zeros((mx.n_out, len(bands)))
        fl2 = np.full_like(e2, np.nan)
        for b, sel in enumerate(members):
            norm = np.sum(np.abs(Hx[:, sel]) ** 2, axis=1)
            if np.any(norm <= 0):
                bad = table["key"].iloc[int(np.argmin(norm))]
                raise ComparisonError(f"channel {bad!r}: measured response is zero over band {labels[b]}")
            w[:, sel] = d2[:, sel] / norm[:, None]
            e2[:, b] = w[:, sel].sum(axis=1)
            if sigma2 is not None:
                phi[:, sel] = sigma2[:, sel] / norm[:, None]
                fl2[:, b] = phi[:, sel].sum(axis=1)
        x2 = e2 if sigma2 is None else np.maximum(e2 - fl2, 0.0)  # error above the noise floor
        total, total_x = float(e2.sum()), float(x2.sum())

        def shares(mask_rows=slice(None), mask_cols=slice(None)):
            s = float(e2[mask_rows][:, mask_cols].sum() / total) if total > 0 else 0.0
            xs = float(x2[mask_rows][:, mask_cols].sum() / total_x) if total_x > 0 else 0.0
            return s, xs

        table["band_error"] = np.sqrt(e2.mean(axis=1))
        table["floor"] = np.sqrt(fl2.mean(axis=1))
        table["excess"] = np.sqrt(x2.mean(axis=1))
        table["share"] = e2.sum(axis=1) / total if total > 0 else 0.0
        table["excess_share"] = x2.sum(axis=1) / total_x if total_x > 0 else 0.0

        keys = list(table["key"])
        band_table = pd.DataFrame({
            "band": labels, "lo_hz": [b[0] for b in bands], "hi_hz": [b[1] for b in bands],
            "n_lines": [int(m.sum()) for m in members], "error": np.sqrt(e2.mean(axis=0)),
            "floor": np.sqrt(fl2.mean(axis=0)), "excess": np.sqrt(x2.mean(axis=0)),
            "share": [shares(mask_cols=[b])[0] for b in range(len(bands))],
            "excess_share": [shares(mask_cols=[b])[1] for b in range(len(bands))]})

        def groups(col):
            present = set(table[col])
            order = [g for g in BODIES if g in present] if col == "body" else sorted(present)
            rows, per_band = [], []
            for g in order:
                m = (table[col] == g).to_numpy()
                s, xs = shares(mask_rows=m)
                rows.append({col: g, "n_channels": int(m.sum()), "error": float(np.sqrt(e2[m].mean())),
                             "floor": float(np.sqrt(fl2[m].mean())), "excess": float(np.sqrt(x2[m].mean())),
                             "share": s, "excess_share": xs})
                per_band.append(np.sqrt(e2[m].mean(axis=0)))
            return pd.DataFrame(rows), pd.DataFrame(per_band, index=order, columns=labels)

        body_table, body_band = groups("body")
        part_table, _ = groups("part")

        with np.errstate(divide="ignore", invalid="ignore"):
            emap = 20 * np.log10(np.abs(Hm) / np.abs(Hx))
        emap = np.where(np.isfinite(emap), emap, np.nan)

        in_band = (f >= band[0]) & (f <= band[1])
        ref = np.mean(np.abs(Hx[:, in_band if in_band.any() else slice(None)]) ** 2, axis=1)
        ref = np.where(ref > 0, ref, 1.0)
        ind_x = np.mean(np.abs(Hx) ** 2 / ref[:, None], axis=0)
        ind_m = np.mean(np.abs(Hm) ** 2 / ref[:, None], axis=0)
        peaks = _peak_table(f, Hx, Hm, self.peak_prominence_db, self.peak_tolerance, n_min,
                            d2, w, phi, sigma2, total, total_x)
        ranking = _ranking(table, band_table, body_table, part_table, peaks, by_excess=sigma2 is not None)

        values = {
            "channels": table, "band_hz": band, "summary_db": summary_db, "bands_hz": bands,
            "peak_min_channels": int(n_min),
            "measurements": tuple(self.measurements), "summary": float(np.sqrt(e2.mean())),
            "noise_floor": float(np.sqrt(fl2.mean())), "bands": band_table,
            "band_errors": pd.DataFrame(np.sqrt(e2), index=keys, columns=labels),
            "band_floors": pd.DataFrame(np.sqrt(fl2), index=keys, columns=labels),
            "body_band_errors": body_band, "bodies": body_table, "parts": part_table, "error_map_db": emap,
            "line_share": w / total if total > 0 else np.zeros_like(w), "indicator_measured": ind_x,
            "indicator_model": ind_m, "peaks": peaks, "ranking": ranking}
        for name, value in values.items():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    # ------------------------------------------------------------------ views
    @property
    def keys(self) -> tuple[str, ...]:
        """Row keys of the channels (``setup/name``, or the name for an unnamed single setup)."""
        return tuple(self.channels["key"])

    @property
    def above_floor(self) -> float:
        """``summary / noise_floor``: 1 means the model is as good as the data can tell."""
        return self.summary / self.noise_floor if self.noise_floor > 0 else float("nan")

    def where(self, top: int = 3) -> pd.DataFrame:
        """Where the model fails: the top channels, bands, bodies, parts and peaks by share of the error.

        The share is that of the error above the noise floor when the floor is
        known (module docstring), of the whole error otherwise.

        Returns
        -------
        pandas.DataFrame
            Rows of :attr:`ranking` with ``rank <= top``, kinds in the order
            channel, band, body, part, peak.
        """
        if top < 1:
            raise ComparisonError(f"top must be >= 1, got {top!r}")
        return self.ranking[self.ranking["rank"] <= top].reset_index(drop=True)

    def localise(self, lo_hz: float, hi_hz: float, by: str = "part") -> pd.DataFrame:
        """Where the misfit inside one frequency window sits (e.g. around a peak without partner).

        Parameters
        ----------
        lo_hz, hi_hz : float
            The window [Hz], inclusive.
        by : {"part", "body", "channel", "setup"}
            Grouping of the channels.

        Returns
        -------
        pandas.DataFrame
            Per group, largest first: ``n_channels``, ``error`` (RMS over the
            group's channels of ``‖H_m − H_x‖/‖H_x‖`` over the window),
            ``floor`` (the same for the noise floor), ``share`` (of the summed
            squared window errors).
        """
        cols = {"part": "part", "body": "body", "channel": "key", "setup": "setup"}
        if by not in cols:
            raise ComparisonError(f"by must be one of {sorted(cols)}, got {by!r}")
        f = self.measured.freqs_hz
        sel = (f >= lo_hz) & (f <= hi_hz)
        if not sel.any():
            raise ComparisonError(f"window {lo_hz:g}–{hi_hz:g} Hz holds no frequency line "
                                  f"({f[0]:g}–{f[-1]:g} Hz)")
        Hx, Hm = self.measured.data[:, 0, sel], self.model.data[:, 0, sel]
        den = np.sum(np.abs(Hx) ** 2, axis=1)
        e2 = np.sum(np.abs(Hm - Hx) ** 2, axis=1) / den
        sigma2 = h1_variance(self.measured)
        fl2 = np.full_like(e2, np.nan) if sigma2 is None else sigma2[:, sel].sum(axis=1) / den
        t = pd.DataFrame({"group": self.channels[cols[by]].to_numpy(), "e2": e2, "fl2": fl2})
        g = t.groupby("group", sort=False)
        out = pd.DataFrame({"n_channels": g.size(), "error": np.sqrt(g["e2"].mean()),
                            "floor": np.sqrt(g["fl2"].mean()), "share": g["e2"].sum() / e2.sum()})
        return out.sort_values("error", ascending=False).rename_axis(by).reset_index()

    def describe(self, top: int = 3) -> str:
        """A few lines of plain text: the figure of merit, its floor, and where the error sits."""
        lines = [f"model vs measurement {self.band_hz[0]:g}–{self.band_hz[1]:g} Hz, {len(self.channels)} channels: "
                 f"error E = {100 * self.summary:.2f} % (noise floor {100 * self.noise_floor:.2f} %, "
                 f"{self.above_floor:.1f}x)"]
        col = "excess_share" if np.isfinite(self.noise_floor) else "share"
        what = "of the error above the noise floor" if col == "excess_share" else "of the error"
        lines[0] += f"; shares {what}:"
        for kind, rows in self.where(top).groupby("kind", sort=False):
            items = ", ".join(f"{r['name']} ({100 * r[col]:.0f} %)" for _, r in rows.iterrows())
            lines.append(f"  worst {'bodies' if kind == 'body' else kind + 's'}: {items}")
        missing = self.peaks[self.peaks["status"] == "measured only"]
        if len(missing):
            lines.append("  measured peaks without model partner: "
                         + ", ".join(f"{x:.1f} Hz" for x in missing["f_measured_hz"]))
        extra = self.peaks[self.peaks["status"] == "model only"]
        if len(extra):
            lines.append("  model peaks without measured partner: "
                         + ", ".join(f"{x:.1f} Hz" for x in extra["f_model_hz"]))
        return "\n".join(lines)


def _complete_table(table: pd.DataFrame, outputs: Sequence[str]) -> pd.DataFrame:
    """Add ``channel, key, setup, body, side, part`` where missing."""
    t = table.copy()
    if "channel" not in t:
        t["channel"] = t["name"].astype(str) if "name" in t else list(outputs)
    if "key" not in t:
        t["key"] = list(outputs)
    if "setup" not in t:
        t["setup"] = ""
    t["setup"] = t["setup"].fillna("").astype(str)
    if "body" not in t:
        t["body"] = [infer_body(c) for c in t["channel"]]
    t["body"] = [b if b in BODIES else "other" for b in t["body"].fillna("other").astype(str)]
    if "side" not in t:
        ys = t["y"].to_numpy(float) if "y" in t else [None] * len(t)
        t["side"] = [infer_side(c, y) for c, y in zip(t["channel"], ys)]
    t["side"] = t["side"].fillna("").astype(str)
    if "part" not in t:
        t["part"] = [_part(b, s) for b, s in zip(t["body"], t["side"])]
    if t["key"].duplicated().any():
        dup = sorted(set(t["key"][t["key"].duplicated()]))
        raise ComparisonError(f"channel keys must be unique, repeated: {dup}")
    front = ["key", "channel", "setup", "body", "side", "part"]
    return t[front + [c for c in t.columns if c not in front]]


def h1_variance(frf: FrequencyResponse) -> np.ndarray | None:
    """Expected squared complex random error of an H1 estimate, per output and line (module docstring)."""
    if frf.coherence is None or frf.n_averages is None:
        log.info("no coherence or averaging count on the measured FRF: the noise floor is unknown (NaN)")
        return None
    n = np.asarray(frf.n_averages, float)
    if np.any(n < 2):
        log.info("outputs averaged over a single hit: the noise floor is unknown (NaN)")
        return None
    g2 = np.clip(frf.coherence[:, 0], 1e-12, 1.0)
    return np.abs(frf.data[:, 0]) ** 2 * (1.0 - g2) / (g2 * (n[:, None] - 1.0))


def _refine(f: np.ndarray, y: np.ndarray, k: int) -> float:
    """Peak frequency from a parabola through lines k-1, k, k+1 of y."""
    if 0 < k < len(f) - 1:
        a, b, c = y[k - 1], y[k], y[k + 1]
        den = a - 2 * b + c
        if den < 0:
            return float(f[k] + 0.25 * (a - c) / den * (f[k + 1] - f[k - 1]))
    return float(f[k])


def channel_peaks(freqs_hz: np.ndarray, H: np.ndarray, prominence_db: float,
                  random_error: np.ndarray | None = None, max_random_error: float = 0.05) -> pd.DataFrame:
    """Peaks of every channel's ``20 log10 |H|``: ``row, f_hz, prominence_db`` (module docstring).

    ``random_error`` (same shape as ``H``): normalised random error ``ε`` of a
    measured H1; peaks whose line has ``ε > max_random_error`` are noise in a
    notch, not resonances, and are dropped.
    """
    rows = []
    for j, h in enumerate(np.asarray(H)):
        db = 20 * np.log10(np.maximum(np.abs(h), 1e-300))
        idx, props = find_peaks(db, prominence=prominence_db)
        keep = np.ones(idx.size, bool) if random_error is None else random_error[j, idx] <= max_random_error
        rows += [(j, _refine(freqs_hz, db, k), float(p)) for k, p in zip(idx[keep], props["prominences"][keep])]
    return pd.DataFrame(rows, columns=["row", "f_hz", "prominence_db"])


def cluster_peaks(peaks: pd.DataFrame, df_hz: float, min_channels: int, rel_width: float = 0.0025) -> pd.DataFrame:
    """Resonances: the densest groups of per-channel peaks, seen on at least ``min_channels`` channels.

    Greedy: the channel peak with the most other peaks within
    ``±max(df, rel_width f)`` seeds a group of those peaks (one per channel,
    the closest), which are removed; repeat while a group would hold
    ``min_channels`` channels. Unlike single-linkage grouping this does not
    chain two close modes (71.5 and 72.6 Hz) into one through stray peaks
    between them.

    Returns ``f_hz`` (median of the group), ``n_channels``, ``prominence_db`` (largest), by frequency.
    """
    cols = ["f_hz", "n_channels", "prominence_db"]
    if peaks.empty:
        return pd.DataFrame(columns=cols)
    p = peaks.sort_values("f_hz", kind="stable").reset_index(drop=True)
    f = p["f_hz"].to_numpy(float)
    rows = p["row"].to_numpy()
    prom = p["prominence_db"].to_numpy(float)
    half = np.maximum(df_hz, rel_width * f)
    alive = np.ones(f.size, bool)
    out = []
    while alive.any():
        idx = np.flatnonzero(alive)
        fa = f[idx]
        lo = np.searchsorted(fa, fa - half[idx], side="left")
        hi = np.searchsorted(fa, fa + half[idx], side="right")
        counts = hi - lo
        best = int(np.argmax(counts + 1e-6 * prom[idx] / (1 + prom[idx].max())))
        if counts[best] < min_channels:
            break
        members = idx[lo[best]:hi[best]]
        centre = fa[best]
        keep = {}
        for m in members:  # one peak per channel: the closest to the seed
            if rows[m] not in keep or abs(f[m] - centre) < abs(f[keep[rows[m]]] - centre):
                keep[rows[m]] = m
        chosen = np.array(list(keep.values()))
        if chosen.size >= min_channels:
            out.append((float(np.median(f[chosen])), int(chosen.size), float(prom[chosen].max())))
            alive[members] = False
        else:
            alive[idx[best]] = False
    return pd.DataFrame(sorted(out), columns=cols)


def _peak_table(f, Hx, Hm, prominence_db, tol, min_channels, d2, w, phi, sigma2, total, total_x
                ) -> pd.DataFrame:
    df = float(np.median(np.diff(f))) if f.size > 1 else 1.0
    n_min = max(1, min(min_channels, Hx.shape[0]))
    eps = None
    if sigma2 is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            eps = np.sqrt(sigma2 / (2 * np.abs(Hx) ** 2))
        eps = np.where(np.isfinite(eps), eps, np.inf)
    px = cluster_peaks(channel_peaks(f, Hx, prominence_db, eps), df, n_min)
    pm = cluster_peaks(channel_peaks(f, Hm, prominence_db), df, n_min)
    fx, fm = px["f_hz"].to_numpy(float), pm["f_hz"].to_numpy(float)
    pairs = []
    if fx.size and fm.size:
        cost = np.abs(fm[None, :] - fx[:, None]) / fx[:, None]
        r, c = linear_sum_assignment(np.where(cost <= tol, cost, 1e6))
        pairs = [(i, j) for i, j in zip(r, c) if cost[i, j] <= tol]
    mi = {i for i, _ in pairs}
    mj = {j for _, j in pairs}
    rows = [("matched", i, j) for i, j in pairs]
    rows += [("measured only", i, None) for i in range(fx.size) if i not in mi]
    rows += [("model only", None, j) for j in range(fm.size) if j not in mj]
    cols = ["status", "f_measured_hz", "f_model_hz", "shift_hz", "shift_pct", "n_channels_measured",
            "n_channels_model", "prominence_measured_db", "prominence_model_db", "lo_hz", "hi_hz", "error",
            "share", "excess_share"]
    if not rows:
        return pd.DataFrame(columns=cols)
    recs = []
    for status, i, j in rows:
        a = fx[i] if i is not None else np.nan
        b = fm[j] if j is not None else np.nan
        recs.append({"status": status, "f_measured_hz": a, "f_model_hz": b, "shift_hz": b - a,
                     "shift_pct": 100 * (b - a) / a if i is not None else np.nan,
                     "n_channels_measured": int(px["n_channels"].iloc[i]) if i is not None else 0,
                     "n_channels_model": int(pm["n_channels"].iloc[j]) if j is not None else 0,
                     "prominence_measured_db": float(px["prominence_db"].iloc[i]) if i is not None else np.nan,
                     "prominence_model_db": float(pm["prominence_db"].iloc[j]) if j is not None else np.nan})
    t = pd.DataFrame(recs)
    t["_lo"] = t[["f_measured_hz", "f_model_hz"]].min(axis=1)
    t["_hi"] = t[["f_measured_hz", "f_model_hz"]].max(axis=1)
    t = t.sort_values("_lo", kind="stable").reset_index(drop=True)
    lo, hi = t["_lo"].to_numpy(), t["_hi"].to_numpy()
    win_lo, win_hi = lo * (1 - tol / 2), hi * (1 + tol / 2)
    for k in range(len(t) - 1):  # clip half way to the neighbour
        if win_hi[k] > win_lo[k + 1]:
            mid = 0.5 * (hi[k] + lo[k + 1])
            win_hi[k] = min(win_hi[k], mid)
            win_lo[k + 1] = max(win_lo[k + 1], mid)
    err, share, xshare = [], [], []
    for k in range(len(t)):
        sel = (f >= win_lo[k]) & (f <= win_hi[k])
        if sel.any():
            num = d2[:, sel].sum(axis=1)
            den = np.sum(np.abs(Hx[:, sel]) ** 2, axis=1)
            err.append(float(np.sqrt(np.nanmean(num / np.where(den > 0, den, np.nan)))))
            ws = w[:, sel].sum(axis=1)
            share.append(float(ws.sum() / total) if total > 0 else 0.0)
            x = np.maximum(ws - np.nan_to_num(phi[:, sel]).sum(axis=1), 0.0)
            xshare.append(float(x.sum() / total_x) if total_x > 0 else 0.0)
        else:
            err.append(np.nan), share.append(0.0), xshare.append(0.0)
    t["lo_hz"], t["hi_hz"], t["error"], t["share"], t["excess_share"] = win_lo, win_hi, err, share, xshare
    return t[cols]


def _peak_name(row) -> str:
    if row["status"] == "matched":
        return f"{row['f_measured_hz']:.1f} Hz (model {row['f_model_hz']:.1f} Hz, {row['shift_pct']:+.2f} %)"
    if row["status"] == "measured only":
        return f"{row['f_measured_hz']:.1f} Hz (measured only)"
    return f"{row['f_model_hz']:.1f} Hz (model only)"


def _ranking(table, bands, bodies, parts, peaks, by_excess: bool) -> pd.DataFrame:
    key = "excess_share" if by_excess else "share"
    frames = []
    for kind, df, name_col, err_col in (("channel", table, "key", "band_error"), ("band", bands, "band", "error"),
                                        ("body", bodies, "body", "error"), ("part", parts, "part", "error")):
        frames.append(pd.DataFrame({"kind": kind, "name": df[name_col].astype(str).to_numpy(),
                                    "share": df["share"].to_numpy(float),
                                    "excess_share": df["excess_share"].to_numpy(float),
                                    "error": df[err_col].to_numpy(float)}))
    if len(peaks):
        frames.append(pd.DataFrame({"kind": "peak", "name": [_peak_name(r) for _, r in peaks.iterrows()],
                                    "share": peaks["share"].to_numpy(float),
                                    "excess_share": peaks["excess_share"].to_numpy(float),
                                    "error": peaks["error"].to_numpy(float)}))
    out = []
    for df in frames:
        df = df.sort_values([key, "share"], ascending=False, kind="stable").reset_index(drop=True)
        df["rank"] = np.arange(1, len(df) + 1)
        out.append(df)
    return pd.concat(out, ignore_index=True)


# --------------------------------------------------------------------------- building comparisons
def _normalise_measurements(measurements) -> list[tuple]:
    """``(setup, FrequencyResponse, channel table, noise variance or None)`` from the accepted input forms."""
    def is_measurement(m):
        return hasattr(m, "frf") and hasattr(m, "channels") and hasattr(m, "setup")

    if isinstance(measurements, Mapping):
        items = [(str(k), *v) for k, v in measurements.items()]
    else:
        if is_measurement(measurements) or (isinstance(measurements, tuple) and len(measurements) in (2, 3, 4) and any(
                isinstance(x, FrequencyResponse) for x in measurements)):
            measurements = [measurements]
        items = []
        for k, m in enumerate(measurements):
            if is_measurement(m):
                items.append((m.setup, m.frf, m.channels, getattr(m, "noise_variance", None)))
                continue
            if not isinstance(m, (tuple, list)) or len(m) not in (2, 3, 4):
                raise ComparisonError(f"measurement {k}: expected a receptance.diagnosis.Measurement, "
                                      f"(FrequencyResponse, channel table) or (setup, FrequencyResponse, channel "
                                      f"table), got {type(m).__name__}")
            items.append(tuple(m) if len(m) >= 3 else (None, *m))
    items = [tuple(it) + (None,) * (4 - len(it)) for it in items]
    out = []
    for k, (setup, frf, table, var) in enumerate(items):
        if not isinstance(frf, FrequencyResponse):
            raise ComparisonError(f"measurement {k}: expected a FrequencyResponse, got {type(frf).__name__}")
        if not isinstance(table, pd.DataFrame) or "quantity" not in table or "name" not in table:
            raise ComparisonError(f"measurement {k}: the channel table must be a DataFrame with 'name' and "
                                  f"'quantity' columns (the setup's *_channels.csv)")
        if setup is None:
            found = sorted(set(table["setup"].dropna().astype(str))) if "setup" in table else []
            if len(found) == 1:
                setup = found[0]
            elif len(items) > 1:
                setup = f"setup{k + 1}"
            else:
                setup = ""
        out.append((str(setup), frf, table, var))
    if not out:
        raise ComparisonError("no measurement to compare with")
    names = [s for s, _, _, _ in out]
    if len(set(names)) != len(names):
        raise ComparisonError(f"setup names must be unique, got {names}; pass a dict {{setup: (frf, table)}}")
    return out


def _model_response(model, setup: str, k: int, H: FrequencyResponse, table: pd.DataFrame, order: pd.DataFrame
                    ) -> FrequencyResponse:
    """The model's accelerance at the measured outputs and lines of one setup."""
    if hasattr(model, "frf_at_channels"):
        full = pd.concat([order, table[table["quantity"] == "force"]], ignore_index=True)
        M = model.frf_at_channels(full, H.freqs_hz, decay=H.exp_window_decay)
        name = getattr(model, "name", type(model).__name__)
        return FrequencyResponse(H.freqs_hz, M.data, H.outputs, H.inputs, "accelerance",
                                 exp_window_decay=H.exp_window_decay,
                                 history=tuple(M.history) + (f"model {name!r} at the test's channels",))
    if isinstance(model, Mapping):
        if setup not in model:
            raise ComparisonError(f"no model response for setup {setup!r}; given for {sorted(model)}")
        M = model[setup]
    elif isinstance(model, FrequencyResponse):
        M = model
    elif isinstance(model, (list, tuple)):
        M = model[k]
    else:
        raise ComparisonError(f"model must be a ModalModel (or have frf_at_channels), a FrequencyResponse, or one "
                              f"per setup; got {type(model).__name__}")
    if not isinstance(M, FrequencyResponse):
        raise ComparisonError(f"setup {setup!r}: model response must be a FrequencyResponse, got {type(M).__name__}")
    if M.quantity != "accelerance":
        M = M.as_quantity("accelerance")
    missing = [o for o in H.outputs if o not in M.outputs]
    if missing:
        raise ComparisonError(f"setup {setup!r}: the model response lacks output(s) {missing}")
    idx = np.searchsorted(M.freqs_hz, H.freqs_hz).clip(0, len(M.freqs_hz) - 1)
    lower = np.clip(idx - 1, 0, None)
    idx = np.where(np.abs(M.freqs_hz[lower] - H.freqs_hz) < np.abs(M.freqs_hz[idx] - H.freqs_hz), lower, idx)
    if not np.allclose(M.freqs_hz[idx], H.freqs_hz, rtol=1e-9, atol=1e-9):
        raise ComparisonError(f"setup {setup!r}: the model response is not given on the measured frequency lines "
                              f"({H.freqs_hz[0]:g}–{H.freqs_hz[-1]:g} Hz, {H.freqs_hz.size} lines)")
    Ms = M.select(outputs=list(H.outputs))
    return FrequencyResponse(H.freqs_hz, Ms.data[:, :1, idx], H.outputs, H.inputs, "accelerance",
                             exp_window_decay=H.exp_window_decay, history=Ms.history)


@one_blas_thread
def compare(model, measurements, *, band_hz: tuple[float, float] | None = (10.0, 500.0),
            bands: Sequence[float] | Sequence[tuple[float, float]] | None = None,
            bodies: Mapping[str, str] | Callable[[str], str] | None = None,
            peak_prominence_db: float = 3.0, peak_tolerance: float = 0.03, peak_min_channels: int | None = None
            ) -> Comparison:
    """Compare a model with the measured FRFs of one or more hammer setups, and localise the error.

    Parameters
    ----------
    model : ModalModel, FrequencyResponse, or a list/dict of FrequencyResponse
        A :class:`~receptance.modal_model.ModalModel` (or anything with its
        ``frf_at_channels(channels, freqs_hz, decay=)``) is evaluated at each
        setup's sensors, driven at its force channel, through the setup's
        exponential window. Alternatively the model's accelerance already
        evaluated: one FrequencyResponse per setup (in the order of
        ``measurements``, or a dict by setup name) whose outputs include the
        measured ones, on the measured lines.
    measurements : (FrequencyResponse, DataFrame) or a list / dict of them
        Measured accelerance (``ema.estimate_frf``) with its setup's channel
        table (including the force row). Items may also be
        ``(setup, frf, table)`` or :class:`receptance.diagnosis.Measurement`
        objects (which carry a noise estimate when the FRF has no
        coherence); a dict maps setup names to ``(frf, table)``.
        The setup name defaults to the table's ``setup`` column.
    band_hz : (float, float) or None
        Band compared [Hz]; None: each measurement's full range.
    bands : sequence, optional
        Band edges ``[10, 20, 40, ...]`` or ``(lo, hi)`` pairs; default
        octaves over ``band_hz`` (:func:`octave_bands`).
    bodies : mapping or callable, optional
        Body of each channel (by channel name or key): overrides the table's
        ``body`` column and the name rule of :func:`infer_body`.
    peak_prominence_db, peak_tolerance, peak_min_channels
        Peak detection (prominence of a channel's peak in dB, number of
        channels that must show it) and matching tolerance (relative
        frequency); module docstring.

    Returns
    -------
    Comparison
        Channel rows keyed ``setup/name`` (just ``name`` for a single
        measurement without a setup label).

    Raises
    ------
    ComparisonError
        Measured outputs missing from the channel table, setups on different
        frequency lines, a model response that does not cover the measured
        outputs or lines, a band without lines.
    """
    items = _normalise_measurements(measurements)
    meas_parts, model_parts, tables, decays, variances = [], [], [], [], []
    lines = None
    for k, (setup, H, table, var) in enumerate(items):
        where = f"setup {setup!r}" if setup else "measurement"
        if H.quantity != "accelerance":
            H = H.as_quantity("accelerance")
        if H.n_in != 1:
            raise ComparisonError(f"{where}: expected a single-reference measurement, got {H.n_in} inputs")
        if var is not None and np.shape(var) != (H.n_out, H.freqs_hz.size):
            raise ComparisonError(f"{where}: the noise variance has shape {np.shape(var)}, the FRF "
                                  f"{(H.n_out, H.freqs_hz.size)}")
        if band_hz is not None:
            if var is not None:
                var = np.asarray(var)[:, (H.freqs_hz >= band_hz[0]) & (H.freqs_hz <= band_hz[1])]
            try:
                H = H.select(band_hz=band_hz)
            except ValueError as exc:
                raise ComparisonError(f"{where}: {exc}") from exc
        acc = table[table["quantity"] == "acceleration"]
        names = acc["name"].astype(str)
        missing = [o for o in H.outputs if o not in set(names)]
        if missing:
            raise ComparisonError(f"{where}: measured output(s) {missing} are not acceleration channels of the "
                                  f"channel table")
        if (table["quantity"] == "force").sum() != 1 and hasattr(model, "frf_at_channels"):
            raise ComparisonError(f"{where}: the channel table must have exactly one force row")
        order = acc.set_index(names).loc[list(H.outputs)].reset_index(drop=True)
        if lines is None:
            lines = H.freqs_hz
        elif H.freqs_hz.shape != lines.shape or not np.allclose(H.freqs_hz, lines, rtol=1e-9):
            raise ComparisonError(f"{where}: frequency lines differ from the first setup's ({H.freqs_hz.size} vs "
                                  f"{lines.size} lines); estimate every setup with the same band and record length")
        M = _model_response(model, setup, k, H, table, order)
        keys = [f"{setup}/{o}" if setup else o for o in H.outputs]
        t = pd.DataFrame({"key": keys, "channel": list(H.outputs), "setup": setup})
        for col in ("node", "x", "y", "z", "dx", "dy", "dz", "fe_node", "body"):
            if col in order:
                t[col] = order[col].to_numpy()
        t["n_averages"] = H.n_averages if H.n_averages is not None else np.nan
        t["exp_window_decay"] = H.exp_window_decay
        meas_parts.append(H)
        model_parts.append(M)
        variances.append(var)
        tables.append(t)
        decays.append(H.exp_window_decay)
    table = pd.concat(tables, ignore_index=True)
    if bodies is not None:
        def lookup(name: str, key: str):
            return bodies(name) if callable(bodies) else bodies.get(key, bodies.get(name))

        prior = table["body"] if "body" in table else pd.Series([None] * len(table))
        table["body"] = [lookup(n, k) or (p if isinstance(p, str) else infer_body(n))
                         for n, k, p in zip(table["channel"], table["key"], prior)]
        bad = sorted({b for b in table["body"] if b not in BODIES})
        if bad:
            raise ComparisonError(f"bodies must be among {BODIES}, got {bad}")
    keys = tuple(table["key"])

    def stack(parts, coherence: bool):
        data = np.concatenate([p.data for p in parts], axis=0)
        coh = None
        if coherence and all(p.coherence is not None for p in parts):
            coh = np.concatenate([p.coherence for p in parts], axis=0)
        navg = None
        if coherence and all(p.n_averages is not None for p in parts):
            navg = np.concatenate([p.n_averages for p in parts])
        same = all(np.isclose(d, decays[0]) for d in decays)
        hist = tuple(parts[0].history)
        if not same:
            hist += (f"setups stacked with different exponential windows a = {[round(d, 6) for d in decays]} 1/s; "
                     f"per-channel values in Comparison.channels['exp_window_decay']",)
        return FrequencyResponse(lines, data, keys, parts[0].inputs, "accelerance", coherence=coh,
                                 exp_window_decay=decays[0] if same else 0.0, n_averages=navg, history=hist)

    if len({p.inputs for p in meas_parts}) > 1:
        # force channel names may differ between setups; the stack uses the first one's label
        log.info("setups use different force channel names %s; the comparison labels the input %r",
                 [p.inputs[0] for p in meas_parts], meas_parts[0].inputs[0])
        meas_parts = [p.with_history("input relabelled", inputs=meas_parts[0].inputs) for p in meas_parts]
        model_parts = [p.with_history("input relabelled", inputs=meas_parts[0].inputs) for p in model_parts]
    measured = stack(meas_parts, True)
    modelled = stack(model_parts, False)
    band = (float(lines[0]), float(lines[-1])) if band_hz is None else (float(band_hz[0]), float(band_hz[1]))
    band_list = None
    if bands is not None:
        arr = list(bands)
        if arr and np.ndim(arr[0]) == 0:
            edges = np.asarray(arr, float)
            if edges.size < 2 or np.any(np.diff(edges) <= 0):
                raise ComparisonError(f"bands as edges must be increasing with at least two values, got {bands!r}")
            band_list = tuple(zip(edges[:-1], edges[1:]))
        else:
            band_list = tuple((float(a), float(b)) for a, b in arr)
            if any(b <= a for a, b in band_list):
                raise ComparisonError(f"every band must have high > low, got {bands!r}")
    noise = None
    if h1_variance(measured) is None:
        # a setup with coherence gives its H1 variance, one without carries its estimate: the floor is known when
        # every setup has one or the other (a hammer setup beside an FRF file without coherence, or a one-hit setup)
        per_setup = [v if v is not None else h1_variance(p) for v, p in zip(variances, meas_parts)]
        if all(v is not None for v in per_setup):
            noise = np.concatenate([np.asarray(v, float) for v in per_setup], axis=0)
    c = Comparison(measured, modelled, table, band, None, band_list, peak_prominence_db, peak_tolerance,
                   peak_min_channels, tuple(items), noise)
    log.info("%s", c.describe().splitlines()[0])
    return c


def compare_frf(model: ModalModel, measured: FrequencyResponse, channels: pd.DataFrame, *,
                band_hz: tuple[float, float] | None = None) -> Comparison:
    """Compare the model with measured FRFs of one hammer setup (see :func:`compare`).

    Parameters
    ----------
    model : ModalModel
    measured : FrequencyResponse
        Measured accelerance (``ema.estimate_frf``); its ``exp_window_decay``
        is applied to the model too.
    channels : pandas.DataFrame
        The setup's channel table, including the force row (positions,
        directions and FE nodes of sensors and hammer).
    band_hz : (float, float), optional
        Default: the measured frequency range.

    Returns
    -------
    Comparison
    """
    return compare(model, [(measured, channels)], band_hz=band_hz)
