"""The bogie's two wheelsets roll over the same rails one wheelbase apart: what their estimates' correlation says.

The trailing wheelset is a second, independent estimate of the rails the leading one saw (thesis §4.3.3). Along
chainage, wheelset 2's estimate of a rail at ``x + s a`` repeats wheelset 1's at ``x`` (``a`` the wheelbase, ``s``
:attr:`LeadTrail.lead_sign`, +1 when wheelset 1 is on the side of increasing chainage). The normalised
cross-correlation of the whitened estimates over wavelengths longer than a few contact patches
(:func:`lead_trail`) therefore

- peaks at the wheelbase on each rail (:meth:`LeadTrail.wheelbase`, thesis §2.2: the wheelbase is measured when it
  is not given);
- checks the channels against the sensor table (:func:`arrangement_findings`): on the same rail the two estimates
  must correlate *positively* at the lag ``+s a``. Each way the sensor table can contradict the accelerometers
  changes that in a way of its own:

  * an accelerometer read with the wrong sign (mounted upside down, or a sensitivity of the wrong sign) flips its
    rail's correlation to negative (the half model is linear: its estimate flips with it);
  * a wheelset's L and R channels swapped make its estimates match the other wheelset's across the rails;
  * one rail's channels of wheelsets 1 and 2 swapped move that rail's peak to ``−s a``; both rails there mean
    that wheelset 1 is not where the header's direction and orientation put it.

  Each is reported when its correlation is at least :data:`MIN_CORRELATION` and beats what the sensor table
  predicts at the same lag by as much (a clear explanation, not a lucky lag), and the rearrangement as a whole
  beats the table's own best lag by half as much again.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy import fft as sfft

from estimator.inversion import _log_smooth_rms

__all__ = ["LeadTrail", "lead_trail", "arrangement_findings", "MIN_CORRELATION"]

#: smallest normalised lead/trail correlation that measures a wheelbase or explains a channel rearrangement
MIN_CORRELATION = 0.3


@dataclass(frozen=True)
class LeadTrail:
    """Cross-correlations of the two wheelsets' whitened estimates, every rail of one against every rail of the
    other.

    ``products[(r1, r2)][l] = Σ_x e1_r1(x) e2_r2(x + lags_m[l])`` (wheelset 1's estimate of rail ``r1``, wheelset
    2's of ``r2``); ``energy[(w, r)] = Σ e_w,r²``.
    """

    dx_m: float
    lead_sign: int
    range_m: tuple[float, float]
    products: Mapping[tuple[str, str], np.ndarray]
    energy: Mapping[tuple[int, str], float]

    @property
    def lags_m(self) -> np.ndarray:
        n = next(iter(self.products.values())).size
        k = np.arange(n)
        return np.where(k > n // 2, k - n, k) * self.dx_m

    @property
    def rails(self) -> tuple[str, ...]:
        """Rails both wheelsets estimate."""
        return tuple(r for r in "LR" if (1, r) in self.energy and (2, r) in self.energy)

    def correlation(self, r1: str, r2: str) -> np.ndarray:
        """Normalised correlation of wheelset 1's rail ``r1`` with wheelset 2's rail ``r2`` per lag."""
        norm = np.sqrt(self.energy[(1, r1)] * self.energy[(2, r2)])
        return self.products[(r1, r2)] / norm if norm > 0 else np.zeros_like(self.products[(r1, r2)])

    def _searched(self) -> np.ndarray:
        """Indexes of the lags where the sensor table puts wheelset 2 behind wheelset 1, within ``range_m``."""
        lags = self.lags_m
        return np.flatnonzero((self.lead_sign * lags >= self.range_m[0]) & (self.lead_sign * lags <= self.range_m[1]))

    def wheelbase(self) -> tuple[float | None, float]:
        """The wheelbase [m] (the lag of the summed same-rail correlations' peak, refined on a parabola) and the
        normalised correlation there; ``(None, 0)`` when no lag is searched or no rail is on both wheelsets."""
        rails = self.rails
        idx = self._searched()
        if not rails or idx.size == 0:
            return None, 0.0
        num = sum(self.products[(r, r)] for r in rails)
        norm_total = sum(float(np.sqrt(self.energy[(1, r)] * self.energy[(2, r)])) for r in rails)
        k = idx[int(np.argmax(num[idx]))]
        off = 0.0
        if 0 < k < num.size - 1:
            y0, y1, y2 = num[k - 1], num[k], num[k + 1]
            den = y0 - 2 * y1 + y2
            off = 0.5 * (y0 - y2) / den if den != 0 else 0.0
        return abs(self.lags_m[k] + off * self.dx_m), float(num[k] / norm_total) if norm_total > 0 else 0.0


def lead_trail(profiles: Mapping[tuple[int, str], np.ndarray], dx_m: float, shortest_m: float, lead_sign: int,
               range_m: tuple[float, float]) -> LeadTrail | None:
    """Whitened cross-correlations of the two wheelsets' rail estimates on a common chainage grid.

    Parameters
    ----------
    profiles : mapping (wheelset, rail) -> ndarray
        Each wheelset's estimate of a rail on the same chainage grid of step ``dx_m`` (NaN where it has none),
        both wheelsets sampled at the same times (the bogie's centre at each grid point).
    dx_m : float
        Grid step [m].
    shortest_m : float
        Shortest wavelength kept [m]: waves shorter than a few contact patches differ between the wheelsets.
    lead_sign : int
        +1 when the sensor table and the header put wheelset 1 on the side of increasing chainage, else −1.
    range_m : (float, float)
        Wheelbases searched [m]; waves longer than the shortest are left out (they give no sharp peak).

    Returns
    -------
    LeadTrail or None
        None when one wheelset has no estimate.
    """
    if not any(w == 1 for w, _ in profiles) or not any(w == 2 for w, _ in profiles):
        return None
    size = next(iter(profiles.values())).size
    # zero padding for the lags searched only (not a whole second run length): the correlation is free of
    # wrap-around up to n - size samples either way
    reach = int(np.ceil(range_m[1] / dx_m)) + 1
    n = sfft.next_fast_len(max(size + reach, 2 * reach + 1))
    k = sfft.rfftfreq(n, dx_m)
    outside = (k < 1.0 / range_m[0]) | (k > 1.0 / shortest_m)
    spectra, energy = {}, {}
    for key, p in profiles.items():
        ok = np.isfinite(p)
        p0 = np.where(ok, p - np.nanmean(p), 0.0) if ok.any() else np.zeros(size)
        # whitened (each spectrum over its one-third-octave RMS): a narrow-band corrugation would otherwise give
        # correlation peaks every wavelength and the lag could land whole wavelengths off; floored at -60 dB of
        # the peak, so what the inversion band left empty stays empty
        P = sfft.rfft(p0, n)
        env = _log_smooth_rms(k, np.abs(P))
        P /= np.maximum(env, 1e-3 * env.max() + 1e-300)
        P[outside] = 0.0
        e = sfft.irfft(P, n)[:size] * ok
        energy[key] = float(np.sum(e ** 2))
        spectra[key] = sfft.rfft(e, n)
    products = {(r1, r2): sfft.irfft(spectra[(2, r2)] * np.conj(spectra[(1, r1)]), n)
                for (w1, r1), (w2, r2) in itertools.product(spectra, spectra) if w1 == 1 and w2 == 2}
    return LeadTrail(dx_m, int(lead_sign), tuple(range_m), products, energy)


@dataclass(frozen=True)
class _Match:
    """What explains one rail pair best at a lag: its correlation there, read with ``sign`` at ``direction``."""

    r1: str
    r2: str
    rho: float          # the pair's correlation as read (sign applied), at the lag
    sign: int           # -1: one of the two channels reads with the wrong sign
    direction: int      # -1: the pair matches with the wheelsets' places exchanged
    as_table: float     # the rail's same-rail correlation where the sensor table puts it (same |lag|)


def _best_arrangement(lt: LeadTrail) -> tuple[list[_Match], float, float] | None:
    """The pairing of rails, per-pair sign and lag direction that best explains the correlations, with the
    wheelbase [m] it finds and the sensor table's own best mean same-rail correlation."""
    rails = lt.rails
    idx = lt._searched()
    if not rails or idx.size == 0:
        return None
    n = next(iter(lt.products.values())).size
    mirrored = (-idx) % n
    pairings = [[(r, r) for r in rails]]
    if len(rails) == 2:
        pairings.append([("L", "R"), ("R", "L")])
    best = None
    for pairing in pairings:
        rho = {p: lt.correlation(*p) for p in pairing}
        # each pair takes its best sign and direction independently: the mean is maximised term by term
        fwd = np.stack([rho[p][idx] for p in pairing])
        back = np.stack([rho[p][mirrored] for p in pairing])
        score = np.maximum(np.abs(fwd), np.abs(back)).mean(axis=0)
        j = int(np.argmax(score))
        if best is None or score[j] > best[0]:
            best = (score[j], pairing, j, fwd[:, j], back[:, j])
    _, pairing, j, fwd, back = best
    same = np.stack([lt.correlation(r, r)[idx] for r in rails])
    table_at = dict(zip(rails, same[:, j]))
    matches = []
    for (r1, r2), f, b in zip(pairing, fwd, back):
        direction = 1 if abs(f) >= abs(b) else -1
        value = f if direction > 0 else b
        matches.append(_Match(r1, r2, abs(float(value)), 1 if value >= 0 else -1, direction, float(table_at[r1])))
    return matches, float(abs(lt.lags_m[idx[j]])), float(same.mean(axis=0).max())


def arrangement_findings(lt: LeadTrail, channels: Mapping[tuple[int, str], str], *, direction: str = "",
                         orientation: str = "") -> list[str]:
    """What the two wheelsets' estimates say against the sensor table (module docstring); empty when they agree.

    Parameters
    ----------
    lt : LeadTrail
    channels : mapping (wheelset, rail) -> str
        The channel each estimate of a rail comes from (named in the findings).
    direction, orientation : str
        The run header's, named when both rails match with the wheelsets' places exchanged.

    Returns
    -------
    list of str
        One sentence per contradiction, naming the channels, the correlations and what to check.
    """
    found = _best_arrangement(lt)
    if found is None:
        return []
    matches, lag, table_best = found
    changed = [m for m in matches if m.r1 != m.r2 or m.sign < 0 or m.direction < 0]
    if not changed:
        return []
    mean = float(np.mean([m.rho for m in matches]))
    clear = all(m.rho >= MIN_CORRELATION and m.rho - m.as_table >= MIN_CORRELATION for m in changed)
    if not clear or mean - table_best < MIN_CORRELATION / 2:
        return []
    ch = lambda w, r: channels.get((w, r), f"wheelset {w} rail {r}")  # noqa: E731
    at = f"one wheelbase apart ({lag:.2f} m)"
    out = []
    if any(m.r1 != m.r2 for m in matches):
        table = " / ".join(f"{m.as_table:+.2f}" for m in matches)
        out.append(f"wheelset 1's estimate of rail L matches wheelset 2's of rail R and the other way round "
                   f"(correlation {' / '.join(f'{m.sign * m.rho:+.2f}' for m in matches)} {at}), where the same "
                   f"rails must match ({table}): one wheelset's L and R channels are swapped ({ch(1, 'L')} and "
                   f"{ch(1, 'R')}, or {ch(2, 'L')} and {ch(2, 'R')}); correct their side in the sensor table")
        return out
    flipped = [m for m in matches if m.sign < 0]
    exchanged = [m for m in matches if m.direction < 0]
    if flipped:
        if len(flipped) == 1:
            who = f"{ch(1, flipped[0].r1)} or {ch(2, flipped[0].r1)} reads"
        else:
            who = (f"wheelset 1's channels ({', '.join(ch(1, m.r1) for m in flipped)}) or wheelset 2's "
                   f"({', '.join(ch(2, m.r1) for m in flipped)}), or one channel of each rail, read")
        out.append(f"rail{'s' if len(flipped) > 1 else ''} {' and '.join(m.r1 for m in flipped)}: the two "
                   f"wheelsets' estimates correlate at {' / '.join(f'{-m.rho:+.2f}' for m in flipped)} {at}, where "
                   f"the same rail's must correlate positively: {who} with the wrong sign (an accelerometer "
                   f"mounted upside down, or a sensitivity of the wrong sign); give the inverted channel a negative "
                   f"sensitivity in the sensor table")
    if len(exchanged) == len(matches) and len(matches) > 1:
        out.append(f"both rails' estimates match with the two wheelsets' places exchanged (correlation "
                   f"{' / '.join(f'{m.rho:+.2f}' for m in exchanged)} {at}): wheelset 1 is not where the header's "
                   f"direction ({direction or 'as read'}) and orientation ({orientation or 'as read'}) put it, or "
                   f"the wheelset numbers in the sensor table are swapped")
    elif exchanged:
        for m in exchanged:
            out.append(f"rail {m.r1}: the two wheelsets' estimates match with their places exchanged "
                       f"(correlation {m.rho:+.2f} {at}, {m.as_table:+.2f} the way the sensor table has them): "
                       f"{ch(1, m.r1)} and {ch(2, m.r1)} are swapped (their wheelset numbers in the sensor table)")
    return out
