"""Options of a field diagnosis, validated when built (each error names the option, its range and the value).

The criterion's thresholds are the lab diagnosis's (:mod:`receptance.diagnosis.fitting`), so that a field
effect is accepted on the same evidence rule as a lab effect; only the cells differ (see
:mod:`estimator.diagnosis.criterion`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from estimator.config import MODELS, _rng
from estimator.errors import ConfigurationError
from estimator.diagnosis.errors import DiagnosisConfigError
from estimator.monitoring.config import MonitoringConfig
from receptance.diagnosis.fitting import BIC_THRESHOLD, MIN_REDUCTION, NOISE_MARGIN, UNDETERMINED_DE

__all__ = ["DiagnosisConfig", "MAX_EFFECTS"]

#: largest number of effects a diagnosis may add (bounded: every round fits the whole catalogue)
MAX_EFFECTS = 6


def _num(name: str, v, lo: float, hi: float, *, lo_open: bool = False, unit: str = "") -> None:
    """The estimator's range check (:func:`estimator.config._rng`), raising the diagnosis's error class."""
    try:
        _rng(name, v, lo, hi, lo_open=lo_open, unit=unit)
    except ConfigurationError as exc:
        raise DiagnosisConfigError(str(exc)) from None


@dataclass(frozen=True)
class DiagnosisConfig:
    """Every option of :func:`estimator.diagnosis.diagnose_field` and :func:`estimator.diagnosis.run_field_diagnosis`.

    Evidence (:mod:`estimator.diagnosis.evidence`)
        ``model``: the transfer-function model diagnosed (``vertical_lateral``: the only one with contact
        angles); ``window_m``: chainage window of one spectrum (Hann taper; a band is used when its nominal
        wavelength is at most ``window_m / min_cycles``, EN 15610 7.5's quarter rule for ``min_cycles`` = 4);
        ``segment_m``: the cells' length along chainage (a whole number of windows); ``shortest_m`` /
        ``longest_m``: the one-third-octave wavelength bands considered (each further limited per window by
        the speed and the inversion band); ``min_reference_snr_db``: a band whose reference lies less than
        this above the reference's own noise is not used; ``transfer_df_hz``: frequency step of the transfer
        functions derived per candidate.

    Criterion (the lab diagnosis's: :mod:`receptance.diagnosis.fitting`)
        ``bic_threshold`` (ΔBIC below minus this), ``min_reduction`` (E falls by at least this share),
        ``noise_margin`` (E above this × the noise floor before the effect), ``undetermined_de`` (a parameter
        whose halving/doubling — or ± a quarter of its range — moves E by less than this share is
        undetermined), ``validation_min_reduction`` (E on the validation stretches where the effect acts must
        fall by at least this share).

    Search
        ``max_effects`` (≤ :data:`MAX_EFFECTS`), ``effects`` (catalogue names tried; ``None``: all),
        ``min_section_m`` (a trackform section is at least this long: shorter stretches are defects, not
        sections: a few sleepers are a defect, not a trackform section), ``workers`` (processes for the candidates; ``None``: the usable cores).

    Comparison
        ``en_window_m``: chainage window of the EN 13231-3 band-index comparison; ``alignment``: the
        monitoring layer's alignment options (runs aligned to the reference's chainage).
    """

    model: str = "vertical_lateral"
    window_m: float = 8.0
    segment_m: float = 24.0
    min_cycles: float = 4.0
    shortest_m: float = 0.016
    longest_m: float = 1.0
    min_reference_snr_db: float = 6.0
    transfer_df_hz: float = 0.5
    bic_threshold: float = BIC_THRESHOLD
    min_reduction: float = MIN_REDUCTION
    noise_margin: float = NOISE_MARGIN
    undetermined_de: float = UNDETERMINED_DE
    validation_min_reduction: float = MIN_REDUCTION
    max_effects: int = 3
    effects: tuple[str, ...] | None = None
    min_section_m: float = 40.0
    workers: int | None = None
    en_window_m: float = 1.0
    alignment: MonitoringConfig = field(default_factory=MonitoringConfig)

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise DiagnosisConfigError(f"model must be one of {MODELS}, got {self.model!r}")
        _num("window_m", self.window_m, 1.0, 100.0, unit="m")
        _num("segment_m", self.segment_m, self.window_m, 1000.0, unit="m")
        k = self.segment_m / self.window_m
        if abs(k - round(k)) > 1e-6:
            raise DiagnosisConfigError(f"segment_m must be a whole number of windows ({self.window_m:g} m), "
                                       f"got {self.segment_m!r}")
        _num("min_cycles", self.min_cycles, 2.0, 50.0)
        _num("shortest_m", self.shortest_m, 1e-3, 1.0, lo_open=True, unit="m")
        _num("longest_m", self.longest_m, self.shortest_m, 10.0, lo_open=True, unit="m")
        _num("min_reference_snr_db", self.min_reference_snr_db, 0.0, 40.0, unit="dB")
        _num("transfer_df_hz", self.transfer_df_hz, 0.01, 2.0, unit="Hz")
        _num("bic_threshold", self.bic_threshold, 0.0, 1e4)
        _num("min_reduction", self.min_reduction, 0.0, 0.9)
        _num("noise_margin", self.noise_margin, 1.0, 10.0)
        _num("undetermined_de", self.undetermined_de, 0.0, 0.5)
        _num("validation_min_reduction", self.validation_min_reduction, 0.0, 0.9)
        if isinstance(self.max_effects, bool) or not isinstance(self.max_effects, int) \
                or not 0 <= self.max_effects <= MAX_EFFECTS:
            raise DiagnosisConfigError(f"max_effects must be an integer in 0..{MAX_EFFECTS}, got {self.max_effects!r}")
        if self.effects is not None:
            object.__setattr__(self, "effects", tuple(str(e) for e in self.effects))
        _num("min_section_m", self.min_section_m, self.window_m, 1e4, unit="m")
        if self.workers is not None and (isinstance(self.workers, bool) or not isinstance(self.workers, int)
                                         or not 1 <= self.workers <= 64):
            raise DiagnosisConfigError(f"workers must be an integer in 1..64 or None, got {self.workers!r}")
        _num("en_window_m", self.en_window_m, 0.1, 100.0, unit="m")
        if not isinstance(self.alignment, MonitoringConfig):
            raise DiagnosisConfigError(f"alignment must be a MonitoringConfig, got {type(self.alignment).__name__}")

    @property
    def windows_per_segment(self) -> int:
        return int(round(self.segment_m / self.window_m))

    def replace(self, **changes) -> "DiagnosisConfig":
        return replace(self, **changes)

    def as_dict(self) -> dict:
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "alignment"}
        out["effects"] = list(self.effects) if self.effects is not None else None
        out["alignment"] = self.alignment.as_dict()
        return out
