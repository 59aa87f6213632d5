"""Rail and wheel roughness of the virtual line: broadband, corrugation, welds, switch, grinding, wheels.

Everything is in metres (positive = material standing up: a bump on the rail,
a larger wheel radius), deterministic for a seed, and generated on the whole
line whatever stretch is simulated, so a short section sees the same rail as a
full run.

**Broadband rail roughness** — a Gaussian random profile whose one-third-octave
spectrum (EN 15610 presentation, dB re 1 µm) is :func:`rail_broadband_target_db`:
the ISO 3095:2013 limit (Fig. 2, 6.2.5; the same 22 values as the "TSI 2007"
curve of EN 15610:2009 Annex B.9.2, :data:`ISO3095_LIMIT_DB`) plus
``offset_db`` = 3 dB from 3.15 mm to 0.4 m — an in-service metro rail that a
noise type test would refuse by a small margin — continued above 0.4 m with
the limit's long-wave slope (2 dB per band) to 2 m, with nothing beyond 2.5 m
(longer waves belong to track geometry, below the band of the axlebox
method). The profile is synthesised in the wavenumber domain: complex Gaussian
coefficients (Rayleigh amplitudes, uniform phases) with a power spectral
density interpolated log-log between band centres and scaled so that each
band's expected mean square is the target's.

**Corrugation** — on the low rail of each curve (:data:`DEFAULT_PATCHES`), two
narrow-band Gaussian components (spectral lines of ±4 % relative width: the
wavelength a fixed-frequency mechanism sets at the curve's steady speed), one
in 30–100 mm and one in 100–300 mm (EN 13231-3 bands, thesis Table 4.1),
tapered over 10 m at the patch ends. Each component's peak-to-peak amplitude
(``2√2 ×`` its RMS over the patch, thesis eq. 4.1) grows linearly with the
days since the patch was last ground: ``pk = residual + rate × days``.
Grinding replaces a component's realisation (new phases).

**Welds** — each thermite weld is a cosine dip (0.05–0.15 mm deep, 0.5–0.9 m
long) with a narrow collar hump (20–40 µm, Gaussian of 12 mm half-width)
on top. **Switch** — a cosine dip of 0.5 mm over 0.35 m at the crossing nose
(wheel transfer from wing rail to nose) and 0.12 mm over 0.6 m at the toe.

**Grinding** — on a grinding day the ground sections (both rails, 2 m tapers)
get a new broadband profile 6 dB below the in-service one, the corrugation is
reset to its residual, and a grinding signature is left: a narrow-band
component at 25 mm (stone facets), 3 µm RMS, worn off by traffic with a 20-day
time constant.

**Wheels** — per wheel a profile periodic in the rolling angle: all orders up
to the 5 mm wavelength with the rail's broadband shape 6 dB lower (disc-braked
trailer wheels, no tread brake), random phases; scenario ``wheel_polygon``
adds one polygonal order of given amplitude to one wheel.

**Contact filter** — a wheel does not follow roughness shorter than its contact
patch. What the wheel feels is the roughness averaged over the Hertzian
contact length with the Hertz pressure's weight ``sqrt(1 − (x/a)²)``
(:func:`contact_filter_kernel`; its transfer is close to ``2 J1(ka)/(ka)``,
−1.2 dB at 50 mm and −2.8 dB at 30 mm for a = 6 mm). The truth holds the
unfiltered rail roughness (what a trolley measures); the passage sees the
filtered one.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import asdict, dataclass

import numpy as np
from scipy import fft as _fft

from .geometry import Line

__all__ = [
    "ISO3095_LIMIT_DB",
    "third_octave_wavelengths",
    "iso3095_limit_db",
    "rail_broadband_target_db",
    "synthesize_profile",
    "CorrugationPatch",
    "Grinding",
    "RoughnessConfig",
    "DEFAULT_PATCHES",
    "RailRoughness",
    "build_rail_roughness",
    "WheelRoughness",
    "build_wheel_roughness",
    "contact_filter_kernel",
    "hertz_semi_axis",
]

#: ISO 3095:2013 Fig. 2 (6.2.5) rail roughness limit, dB re 1 µm, by one-third-octave wavelength [m].
ISO3095_LIMIT_DB: dict[float, float] = {
    0.4: 17.1, 0.315: 15.0, 0.25: 13.0, 0.2: 11.0, 0.16: 9.0, 0.125: 7.0, 0.1: 4.9, 0.08: 2.9, 0.063: 0.9,
    0.05: -1.1, 0.04: -3.2, 0.0315: -5.0, 0.025: -5.6, 0.02: -6.2, 0.016: -6.8, 0.0125: -7.4, 0.01: -8.0,
    0.008: -8.6, 0.0063: -9.2, 0.005: -9.8, 0.004: -10.4, 0.00315: -11.0,
}
R0 = 1e-6  # reference roughness of the levels (1 µm)
LONG_WAVE_SLOPE_DB = 2.0  # per one-third octave above 0.4 m (the limit's slope between 0.125 and 0.4 m)
MAX_WAVELENGTH_M = 2.0


def third_octave_wavelengths(longest: float = 2.0, shortest: float = 0.00315) -> np.ndarray:
    """Exact base-10 one-third-octave centre wavelengths ``10^(n/10)`` m from ``longest`` down to ``shortest``."""
    n_hi = int(np.round(10 * np.log10(longest)))
    n_lo = int(np.round(10 * np.log10(shortest)))
    return 10.0 ** (np.arange(n_hi, n_lo - 1, -1) / 10.0)


def iso3095_limit_db(wavelength_m: np.ndarray) -> np.ndarray:
    """ISO 3095 limit at exact one-third-octave wavelengths (matched to the nominal table within 3 %)."""
    lam = np.atleast_1d(np.asarray(wavelength_m, float))
    nominal = np.array(sorted(ISO3095_LIMIT_DB))
    out = np.empty_like(lam)
    for i, w in enumerate(lam):
        j = int(np.argmin(np.abs(np.log(nominal / w))))
        if abs(np.log(nominal[j] / w)) > 0.03:
            raise ValueError(f"no ISO 3095 limit at {w} m (table: {nominal.min()}-{nominal.max()} m)")
        out[i] = ISO3095_LIMIT_DB[float(nominal[j])]
    return out


def rail_broadband_target_db(wavelength_m: np.ndarray, offset_db: float = 3.0) -> np.ndarray:
    """Target one-third-octave level [dB re 1 µm]: ISO 3095 limit + offset, long-wave slope above 0.4 m."""
    lam = np.atleast_1d(np.asarray(wavelength_m, float))
    out = np.empty_like(lam)
    short = lam <= 0.41
    out[short] = iso3095_limit_db(lam[short]) + offset_db
    bands_above = np.round(10 * np.log10(lam[~short] / 0.4) * 1.0)  # number of bands above 0.4 m
    out[~short] = ISO3095_LIMIT_DB[0.4] + offset_db + LONG_WAVE_SLOPE_DB * bands_above
    return out


def _band_edges(centres_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wavenumber edges [1/m] of one-third-octave bands (base 10)."""
    k = 1.0 / np.asarray(centres_m, float)
    return k * 10 ** (-1 / 20), k * 10 ** (1 / 20)


def synthesize_profile(n: int, dx: float, centres_m: np.ndarray, levels_db: np.ndarray,
                       rng: np.random.Generator, *, periodic: bool = False) -> np.ndarray:
    """A Gaussian random profile whose expected one-third-octave levels are ``levels_db``.

    Parameters
    ----------
    n, dx : int, float
        Number of samples and their spacing [m].
    centres_m, levels_db : array
        Band centre wavelengths and levels [dB re 1 µm].
    rng : numpy Generator
    periodic : bool
        True: the profile is exactly periodic over ``n`` samples (a wheel's circumference); False: it is cut
        from a longer periodic synthesis so its ends are unrelated.

    Returns
    -------
    ndarray (n,)
        Profile in m.
    """
    m = n if periodic else _fft.next_fast_len(int(n * 1.1) + 64)
    k = np.fft.rfftfreq(m, dx)
    lo, hi = _band_edges(centres_m)
    kc = 1.0 / np.asarray(centres_m, float)
    ms = (R0 * 10 ** (np.asarray(levels_db, float) / 20)) ** 2  # band mean square [m^2]
    dens = ms / (hi - lo)
    order = np.argsort(kc)
    psd = np.zeros_like(k)
    inside = (k >= lo.min()) & (k < hi.max())
    psd[inside] = np.exp(np.interp(np.log(k[inside]), np.log(kc[order]), np.log(dens[order])))
    dk = k[1] - k[0]
    # scale each band so its expected mean square is exactly the target's (a smooth spectrum, exact band levels)
    for a, b, target in zip(lo, hi, ms):
        sel = (k >= a) & (k < b)
        got = psd[sel].sum() * dk
        if got > 0:
            psd[sel] *= target / got
    # one-sided PSD S(k) [m^2 per 1/m] -> rfft coefficients: mean square of bin j is 2|C_j|^2/m^2 = S_j dk
    sigma = np.sqrt(psd * dk / 2.0) * m
    coef = (rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size)) * sigma / np.sqrt(2.0)
    coef[0] = 0.0
    if m % 2 == 0:
        coef[-1] = coef[-1].real * np.sqrt(2.0)
    x = _fft.irfft(coef, m)
    if periodic:
        return x
    start = int(rng.integers(0, m - n + 1))
    return x[start:start + n]


def _narrowband(n: int, dx: float, wavelength: float, rel_width: float, rng: np.random.Generator) -> np.ndarray:
    """Unit-RMS Gaussian process with a Gaussian spectral line at 1/wavelength of relative std ``rel_width``."""
    m = _fft.next_fast_len(int(n * 1.1) + 64)
    k = np.fft.rfftfreq(m, dx)
    k0 = 1.0 / wavelength
    amp = np.exp(-0.25 * ((k - k0) / (rel_width * k0)) ** 2)  # sqrt of a Gaussian PSD
    coef = (rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size)) * amp
    x = _fft.irfft(coef, m)[:n]
    return x / np.sqrt(np.mean(x**2))


@dataclass(frozen=True)
class CorrugationPatch:
    """Corrugation on one rail: two narrow-band components, pk-pk growing linearly with days since grinding."""

    id: str
    rail: str
    from_m: float
    to_m: float
    wavelengths_m: tuple[float, float]
    rate_um_per_day: tuple[float, float]
    residual_pk_pk_um: float = 2.0
    taper_m: float = 10.0
    relative_width: float = 0.04

    def envelope(self, x: np.ndarray) -> np.ndarray:
        """1 inside, raised-cosine tapers of ``taper_m`` inside each end, 0 outside."""
        u = np.clip(np.minimum(x - self.from_m, self.to_m - x) / self.taper_m, 0.0, 1.0)
        return np.where((x >= self.from_m) & (x <= self.to_m), 0.5 - 0.5 * np.cos(np.pi * u), 0.0)

    def pk_pk_um(self, days_since_grinding: float) -> tuple[float, float]:
        return tuple(self.residual_pk_pk_um + r * days_since_grinding for r in self.rate_um_per_day)


#: Corrugation on the low rail of both curves (curve 1 turns right: low rail R; curve 2 left: low rail L).
DEFAULT_PATCHES = (
    CorrugationPatch("C1_low", "R", 500.0, 680.0, (0.050, 0.160), (0.40, 0.65)),
    CorrugationPatch("C2_low", "L", 1030.0, 1210.0, (0.063, 0.200), (0.30, 0.50)),
)


@dataclass(frozen=True)
class Grinding:
    """A grinding day: every listed section (both rails) ground on ``date`` (ISO ``YYYY-MM-DD``)."""

    date: str
    sections: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class RoughnessConfig:
    """How the rails are made (see the module docstring)."""

    seed: int = 3095
    dx: float = 1e-3
    offset_db: float = 3.0
    patches: tuple[CorrugationPatch, ...] = DEFAULT_PATCHES
    #: date of the grinding before the campaign (corrugation age is counted from it)
    previous_grinding: str = "2024-01-19"
    grindings: tuple[Grinding, ...] = ()
    ground_level_db: float = -6.0
    signature_wavelength_m: float = 0.025
    signature_rms_m: float = 3e-6
    signature_decay_days: float = 20.0
    weld_depth_m: tuple[float, float] = (0.05e-3, 0.15e-3)
    weld_length_m: tuple[float, float] = (0.5, 0.9)
    weld_collar_m: tuple[float, float] = (20e-6, 40e-6)
    crossing_dip: tuple[float, float] = (0.5e-3, 0.35)  # depth, length
    toe_dip: tuple[float, float] = (0.12e-3, 0.6)

    def parameters(self) -> dict:
        return asdict(self)


def _date(s: str) -> _dt.date:
    return _dt.date.fromisoformat(s)


def _cosine_dip(x: np.ndarray, centre: float, depth: float, length: float) -> np.ndarray:
    u = (x - centre) / length
    return np.where(np.abs(u) < 0.5, -depth * 0.5 * (1 + np.cos(2 * np.pi * u)), 0.0)


@dataclass(frozen=True)
class RailRoughness:
    """The rails of the whole line, per day on demand (:meth:`on`); rows ``L``, ``R``.

    Attributes
    ----------
    x : ndarray
        Chainage grid [m] (uniform, spacing ``config.dx``).
    base, ground : ndarray (2, n)
        In-service broadband profile and the profile left by grinding.
    features : ndarray (2, n)
        Weld dips and collars, switch dips (never ground away).
    welds : list of dict
        Per weld: chainage, rail, depth, length, collar height.
    """

    config: RoughnessConfig
    x: np.ndarray
    base: np.ndarray
    ground: np.ndarray
    features: np.ndarray
    corrugation: dict  # (patch id, epoch) -> (2 components, n_patch) unit-RMS profiles on the patch's slice
    patch_slices: dict
    signature: np.ndarray  # (2, n) unit-RMS grinding signature
    welds: tuple

    def grindings_before(self, date: str) -> list[Grinding]:
        return [g for g in self.config.grindings if _date(g.date) <= _date(date)]

    def _ground_mask(self, date: str) -> tuple[np.ndarray, np.ndarray]:
        """Weight (0..1) of 'ground' per sample, and the days since each sample was last ground (inf: never)."""
        w = np.zeros_like(self.x)
        age = np.full_like(self.x, np.inf)
        for g in self.grindings_before(date):
            days = (_date(date) - _date(g.date)).days
            for a, b in g.sections:
                u = np.clip(np.minimum(self.x - a, b - self.x) / 2.0, 0.0, 1.0)
                wg = np.where((self.x >= a) & (self.x <= b), 0.5 - 0.5 * np.cos(np.pi * u), 0.0)
                w = np.maximum(w, wg)
                age = np.where(wg > 0, np.minimum(age, days), age)
        return w, age

    def patch_state(self, patch: CorrugationPatch, date: str) -> tuple[int, float]:
        """(epoch, days since the patch was last ground) on ``date``: epoch counts the grindings covering it."""
        last = _date(self.config.previous_grinding)
        epoch = 0
        for g in self.grindings_before(date):
            if any(a <= 0.5 * (patch.from_m + patch.to_m) <= b for a, b in g.sections):
                last = _date(g.date)
                epoch += 1
        return epoch, float((_date(date) - last).days)

    def corrugation_on(self, date: str) -> np.ndarray:
        """The corrugation alone on ``date`` (2, n) [m]."""
        out = np.zeros((2, self.x.size))
        for p in self.config.patches:
            epoch, days = self.patch_state(p, date)
            sl = self.patch_slices[p.id]
            comps = self.corrugation[(p.id, epoch)]
            env = p.envelope(self.x[sl])
            row = "LR".index(p.rail)
            for comp, pk in zip(comps, p.pk_pk_um(days)):
                out[row, sl] += env * comp * pk * 1e-6 / (2 * np.sqrt(2))
        return out

    def on(self, date: str) -> np.ndarray:
        """True rail roughness (2, n) [m] on ``date``: broadband (ground where ground) + features + corrugation."""
        c = self.config
        w, age = self._ground_mask(date)
        sig = np.where(np.isfinite(age), c.signature_rms_m * np.exp(-np.where(np.isfinite(age), age, 0.0)
                                                                    / c.signature_decay_days), 0.0)
        r = (1 - w) * self.base + w * (self.ground + sig * self.signature)
        return r + self.features + self.corrugation_on(date)

    def slice(self, from_m: float, to_m: float) -> slice:
        i0 = max(0, int(np.floor((from_m - self.x[0]) / self.config.dx)))
        i1 = min(self.x.size, int(np.ceil((to_m - self.x[0]) / self.config.dx)) + 1)
        return slice(i0, i1)


def build_rail_roughness(line: Line, config: RoughnessConfig = RoughnessConfig()) -> RailRoughness:
    """Generate every component of both rails over the whole line (deterministic for ``config.seed``)."""
    dx = config.dx
    n = int(round(line.length_m / dx)) + 1
    x = np.arange(n) * dx
    centres = third_octave_wavelengths(MAX_WAVELENGTH_M, 0.00315)
    target = rail_broadband_target_db(centres, config.offset_db)
    ss = np.random.SeedSequence(config.seed)
    s_base, s_ground, s_corr, s_sig, s_weld = ss.spawn(5)
    base = np.stack([synthesize_profile(n, dx, centres, target, np.random.default_rng(s)) for s in s_base.spawn(2)])
    ground = np.stack([synthesize_profile(n, dx, centres, target + config.ground_level_db, np.random.default_rng(s))
                       for s in s_ground.spawn(2)])
    signature = np.stack([_narrowband(n, dx, config.signature_wavelength_m, 0.03, np.random.default_rng(s))
                          for s in s_sig.spawn(2)])

    n_epochs = 1 + len(config.grindings)
    corrugation, slices = {}, {}
    for p, sp in zip(config.patches, s_corr.spawn(len(config.patches))):
        sl = slice(int(np.floor(p.from_m / dx)), int(np.ceil(p.to_m / dx)) + 1)
        slices[p.id] = sl
        m = sl.stop - sl.start
        body = p.envelope(x[sl]) >= 1.0
        for epoch, se in enumerate(sp.spawn(n_epochs)):
            comps = []
            for lam, sc in zip(p.wavelengths_m, se.spawn(2)):
                z = _narrowband(m, dx, lam, p.relative_width, np.random.default_rng(sc))
                comps.append(z / np.sqrt(np.mean(z[body] ** 2)))  # unit RMS over the patch body
            corrugation[(p.id, epoch)] = np.stack(comps)

    features = np.zeros((2, n))
    rng = np.random.default_rng(s_weld)
    welds = []
    for wd in line.welds:
        row = "LR".index(wd.rail)
        depth = rng.uniform(*config.weld_depth_m)
        length = rng.uniform(*config.weld_length_m)
        collar = rng.uniform(*config.weld_collar_m)
        sl = slice(max(0, int((wd.chainage_m - length) / dx)), min(n, int((wd.chainage_m + length) / dx) + 1))
        xs = x[sl]
        features[row, sl] += _cosine_dip(xs, wd.chainage_m, depth, length) \
            + collar * np.exp(-0.5 * ((xs - wd.chainage_m) / 0.012) ** 2)
        welds.append({"chainage_m": wd.chainage_m, "rail": wd.rail, "depth_m": depth, "length_m": length,
                      "collar_m": collar})
    switch_features = []
    for sw in line.switches:
        row = "LR".index(sw.crossing_rail)
        features[row] += _cosine_dip(x, sw.crossing_m, *config.crossing_dip)
        features[1 - row] += _cosine_dip(x, sw.from_m + 0.5 * config.toe_dip[1], *config.toe_dip)
        switch_features.append({"switch": sw.id, "crossing_m": sw.crossing_m, "crossing_rail": sw.crossing_rail,
                                "crossing_depth_m": config.crossing_dip[0], "toe_m": sw.from_m})
    return RailRoughness(config, x, base, ground, features, corrugation, slices, signature,
                         tuple(welds) + tuple(switch_features))


# ----------------------------------------------------------------------------------------------- wheels


@dataclass(frozen=True)
class WheelRoughness:
    """Per wheel (ws1 L, ws1 R, ws2 L, ws2 R) a roughness table over one revolution and the true rolling radii."""

    radius_m: np.ndarray  # (4,)
    table: np.ndarray  # (4, m): roughness [m] at angles 2 pi j / m
    polygon: dict | None = None
    level_offset_db: float = -6.0

    def at(self, angle: np.ndarray) -> np.ndarray:
        """Roughness [m] of each wheel at rolling angles ``angle`` (4, n) [rad] (periodic linear interpolation)."""
        m = self.table.shape[1]
        grid = 2 * np.pi * np.arange(m) / m
        angle = np.asarray(angle, float)
        return np.stack([np.interp(angle[w], grid, self.table[w], period=2 * np.pi) for w in range(4)])


def build_wheel_roughness(radius_m: np.ndarray, seed: int, *, level_offset_db: float = -6.0,
                          polygon: dict | None = None, samples: int = 16384) -> WheelRoughness:
    """Wheel profiles periodic over one revolution.

    Parameters
    ----------
    radius_m : array (4,)
        True (worn) rolling radii.
    polygon : dict, optional
        ``{"wheel": index 0-3, "order": n, "amplitude_m": A, "phase_rad": p}``: adds ``A cos(n θ + p)``.
    """
    radius_m = np.asarray(radius_m, float)
    rng = np.random.default_rng(seed)
    tables = []
    for r in radius_m:
        circ = 2 * np.pi * r
        dx = circ / samples
        centres = third_octave_wavelengths(0.8, 0.005)
        levels = rail_broadband_target_db(centres, 3.0) + level_offset_db
        tables.append(synthesize_profile(samples, dx, centres, levels, rng, periodic=True))
    table = np.stack(tables)
    if polygon is not None:
        th = 2 * np.pi * np.arange(samples) / samples
        table[polygon["wheel"]] += polygon["amplitude_m"] * np.cos(polygon["order"] * th + polygon["phase_rad"])
    return WheelRoughness(radius_m, table, polygon, level_offset_db)


# ----------------------------------------------------------------------------------------------- contact filter


def hertz_semi_axis(load_n: float, wheel_radius_m: float = 0.41, rail_crown_radius_m: float = 0.30,
                    youngs_modulus: float = 206e9, poisson: float = 0.28) -> float:
    """Longitudinal semi-axis ``a`` [m] of the Hertz contact, for an equivalent circular contact.

    ``a = (3 N R_e / (4 E*))^(1/3)`` with ``R_e = sqrt(R_wheel R_crown)`` and ``E* = E / (2 (1 − ν²))``
    (two steel bodies); Johnson, *Contact Mechanics*, §4.2 — adequate for a filter whose effect is a few dB.
    """
    e_star = youngs_modulus / (2 * (1 - poisson**2))
    r_e = np.sqrt(wheel_radius_m * rail_crown_radius_m)
    return float((3 * load_n * r_e / (4 * e_star)) ** (1 / 3))


def contact_filter_kernel(semi_axis_m: float, dx: float) -> np.ndarray:
    """Averaging weights over the contact length, Hertz pressure ``sqrt(1 − (x/a)²)``, unit sum."""
    h = int(np.floor(semi_axis_m / dx))
    xs = np.arange(-h, h + 1) * dx
    w = np.sqrt(np.clip(1 - (xs / semi_axis_m) ** 2, 0.0, None))
    return w / w.sum()
