"""Options of the monitoring layer (alignment, averaging, confidence, trends, grinding), validated when built."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

from estimator.config import MODELS
from estimator.config import _rng as _num  # one range check for every option class (names the option)
from estimator.monitoring.errors import MonitoringConfigError

__all__ = ["MonitoringConfig", "DAYS_PER_MONTH"]

#: mean length of a month [days] for growth rates in µm/month
DAYS_PER_MONTH = 365.25 / 12


@dataclass(frozen=True)
class MonitoringConfig:
    """Every option of the monitoring layer.

    Results
        ``model``: the transfer-function model whose estimates are monitored
        (thesis §4.3.6 uses the full wheelset with vertical and lateral
        dynamics); ``window_m``: the chainage window the band indexes are
        stored and averaged on.

    Alignment (:mod:`estimator.monitoring.alignment`)
        ``align_band_mm`` (fine band of the feature signal), ``align_coarse_band_mm``
        (long-wave band of the first, wide search), ``align_window_m`` and
        ``align_step_m`` (correlation windows), ``align_max_lag_m`` (largest
        misplacement searched: metre-scale start offsets plus the odometer's
        scale error over the run), ``align_min_correlation``,
        ``align_min_windows``, ``align_piece_m`` (longest piece of the
        piecewise offset + scale), ``align_max_residual_mm`` and
        ``align_max_scale_error`` (rejection), ``weld_length_m`` (length of the
        dip of the line's weld template).

    Averaging and confidence
        ``confidence`` (two-sided level), ``n_perturbed`` models with
        ``perturbation`` (±, on every modal frequency and damping ratio, thesis
        §4.3.4: 25 models, ±10 %), ``perturbation_seed``, ``placement_shifts_mm``
        and ``placement_axes`` (thesis §4.3.5: ±10, ±30, ±50 mm), ``uncertainty_runs``
        (runs per day whose accelerations go through every perturbed and
        shifted model), ``contact_load_range`` (± share of the wheel load: tare
        to crush load), ``contact_head_radius_m`` (rail head transverse radii
        bounding the contact geometry), ``track_stiffness_factor`` (pad and
        ballast stiffness times and divided by it; 1: none),
        ``track_damping_factor`` (pad and ballast damping, loss factor and
        viscous coefficient together, times and divided by it; 1: none),
        ``track_loss_reference_hz`` (the causal loss law with the trackform's
        stiffness holding at each of these frequencies; empty: none),
        ``track_discrete_supports`` (the discretely supported rail's
        receptance as a variant) — the contact and track sources of
        :mod:`estimator.monitoring.variants` (a zero range, no radius, a
        factor 1, no reference frequency and no discrete supports leave a
        source out);
        ``sensor_noise_rms_m_s2`` (the accelerometer chain's noise, RMS over
        the recorded band, from its datasheet or a standstill recording;
        ``None``: no noise floor, :mod:`estimator.monitoring.floor`).

    Consistency
        ``consistency_min_db``: a disagreement smaller than this is never flagged;
        ``consistency_z``: a disagreement is flagged beyond this many standard
        errors; ``crosstalk_coherence``: coherence between the rails'
        band-filtered estimates above which cross-talk is suspected.

    Trends and grinding
        ``grinding_drop_db`` (a fall of a stretch's band level between two survey
        days beyond this, in at least ``grinding_min_bands`` bands, is a grinding),
        ``grinding_min_length_m``, ``grinding_bands_mm`` (the bands looked at: the
        short-wave band gains the grinding signature), ``thresholds_um`` per band
        (``None``: the estimator's), ``trend_min_days``.
    """

    model: str = "vertical_lateral"
    window_m: float = 1.0
    align_band_mm: tuple[float, float] = (20.0, 1000.0)
    align_coarse_band_mm: tuple[float, float] = (100.0, 1000.0)
    align_window_m: float = 20.0
    align_step_m: float = 10.0
    align_max_lag_m: float = 5.0
    align_min_correlation: float = 0.5
    align_min_windows: int = 3
    align_piece_m: float = 250.0
    align_max_residual_mm: float = 20.0
    align_max_scale_error: float = 0.02
    weld_length_m: float = 0.7
    confidence: float = 0.95
    n_perturbed: int = 25
    perturbation: float = 0.10
    perturbation_seed: int = 0
    placement_shifts_mm: tuple[float, ...] = (10.0, 30.0, 50.0)
    placement_axes: tuple[str, ...] = ("x", "y")
    uncertainty_runs: int = 1
    contact_load_range: float = 0.25
    contact_head_radius_m: tuple[float, ...] = (0.2, 0.5)
    track_stiffness_factor: float = 2.0
    track_damping_factor: float = 2.0
    track_loss_reference_hz: tuple[float, ...] = (10.0, 1000.0)
    track_discrete_supports: bool = True
    sensor_noise_rms_m_s2: float | None = None
    consistency_min_db: float = 2.0
    consistency_z: float = 3.0
    crosstalk_coherence: float = 0.8
    grinding_drop_db: float = 4.0
    grinding_min_bands: int = 2
    grinding_min_length_m: float = 20.0
    grinding_bands_mm: tuple[tuple[float, float], ...] = ((30.0, 100.0), (100.0, 300.0), (300.0, 1000.0))
    thresholds_um: dict | None = None
    trend_min_days: int = 2

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise MonitoringConfigError(f"model must be one of {MODELS}, got {self.model!r}")
        _num("window_m", self.window_m, 0.05, 1000.0, unit="m")
        for name in ("align_band_mm", "align_coarse_band_mm"):
            a, b = getattr(self, name)
            if not (0 < a < b):
                raise MonitoringConfigError(f"{name} must be (short, long) wavelengths in mm with 0 < short < long, "
                                            f"got {(a, b)}")
        _num("align_window_m", self.align_window_m, 1.0, 1000.0, unit="m")
        _num("align_step_m", self.align_step_m, 0.1, self.align_window_m, unit="m")
        _num("align_max_lag_m", self.align_max_lag_m, 0.0, 100.0, lo_open=True, unit="m")
        _num("align_min_correlation", self.align_min_correlation, 0.0, 1.0)
        _num("align_min_windows", self.align_min_windows, 1, 10_000)
        _num("align_piece_m", self.align_piece_m, 1.0, 1e6, unit="m")
        _num("align_max_residual_mm", self.align_max_residual_mm, 0.0, 1e4, lo_open=True, unit="mm")
        _num("align_max_scale_error", self.align_max_scale_error, 0.0, 0.5, lo_open=True)
        _num("weld_length_m", self.weld_length_m, 0.05, 5.0, unit="m")
        _num("confidence", self.confidence, 0.5, 0.999)
        _num("n_perturbed", self.n_perturbed, 0, 1000)
        _num("perturbation", self.perturbation, 0.0, 0.9)
        _num("perturbation_seed", self.perturbation_seed, 0, 2**63)
        for s in self.placement_shifts_mm:
            _num("placement_shifts_mm", s, 0.0, 500.0, lo_open=True, unit="mm")
        bad = [a for a in self.placement_axes if a not in ("x", "y", "z")]
        if bad:
            raise MonitoringConfigError(f"placement_axes must be among x, y, z, got {bad}")
        _num("uncertainty_runs", self.uncertainty_runs, 0, 1000)
        _num("contact_load_range", self.contact_load_range, 0.0, 0.9)
        for r in self.contact_head_radius_m:
            _num("contact_head_radius_m", r, 0.01, 10.0, unit="m")
        _num("track_stiffness_factor", self.track_stiffness_factor, 1.0, 10.0)
        _num("track_damping_factor", self.track_damping_factor, 1.0, 10.0)
        for f in self.track_loss_reference_hz:
            _num("track_loss_reference_hz", f, 0.1, 1e5, unit="Hz")
        object.__setattr__(self, "track_loss_reference_hz", tuple(float(f) for f in self.track_loss_reference_hz))
        if self.sensor_noise_rms_m_s2 is not None:
            _num("sensor_noise_rms_m_s2", self.sensor_noise_rms_m_s2, 0.0, 1e3, lo_open=True, unit="m/s^2")
        object.__setattr__(self, "contact_head_radius_m", tuple(float(r) for r in self.contact_head_radius_m))
        _num("consistency_min_db", self.consistency_min_db, 0.0, 60.0, unit="dB")
        _num("consistency_z", self.consistency_z, 0.5, 20.0)
        _num("crosstalk_coherence", self.crosstalk_coherence, 0.0, 1.0, lo_open=True)
        _num("grinding_drop_db", self.grinding_drop_db, 0.5, 60.0, unit="dB")
        _num("grinding_min_bands", self.grinding_min_bands, 1, len(self.grinding_bands_mm))
        _num("grinding_min_length_m", self.grinding_min_length_m, 0.0, 1e5, unit="m")
        _num("trend_min_days", self.trend_min_days, 2, 10_000)
        object.__setattr__(self, "align_band_mm", tuple(float(v) for v in self.align_band_mm))
        object.__setattr__(self, "align_coarse_band_mm", tuple(float(v) for v in self.align_coarse_band_mm))
        object.__setattr__(self, "placement_shifts_mm", tuple(float(v) for v in self.placement_shifts_mm))
        object.__setattr__(self, "placement_axes", tuple(self.placement_axes))
        object.__setattr__(self, "grinding_bands_mm", tuple((float(a), float(b)) for a, b in self.grinding_bands_mm))
        if self.thresholds_um is not None:
            th = {}
            for k, v in dict(self.thresholds_um).items():
                band = _band_key(k)
                _num(f"thresholds_um[{band[0]:g}-{band[1]:g}]", v, 0.0, 1e5, lo_open=True, unit="um")
                th[band] = float(v)
            object.__setattr__(self, "thresholds_um", th)

    def replace(self, **changes) -> "MonitoringConfig":
        return replace(self, **changes)

    def as_dict(self) -> dict:
        d = asdict(self)
        if self.thresholds_um is not None:
            d["thresholds_um"] = {f"{a:g}-{b:g}": v for (a, b), v in self.thresholds_um.items()}
        return d


def _band_key(k) -> tuple[float, float]:
    """``(30, 100)`` or ``"30-100"`` → ``(30.0, 100.0)``."""
    if isinstance(k, str):
        try:
            a, b = (float(v) for v in k.split("-"))
        except ValueError:
            raise MonitoringConfigError(f"a band is written 'SHORT-LONG' in mm (e.g. '30-100'), got {k!r}") from None
        return a, b
    a, b = k
    return float(a), float(b)


def band_label(band) -> str:
    """``(30.0, 100.0)`` → ``"30-100"`` (the ``band_mm`` column of every table)."""
    a, b = _band_key(band)
    return f"{a:g}-{b:g}"


def parse_band(label) -> tuple[float, float]:
    """``"30-100"`` → ``(30.0, 100.0)``."""
    return _band_key(label)
