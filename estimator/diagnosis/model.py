"""The estimate's band levels on the evidence for any field state — the diagnosis's forward model.

For each segment the transfer function the estimator would use there under
a :class:`~estimator.diagnosis.state.FieldState` (the trackform at the
segment with the state's section changes, the curve's calibrated angles for
the wheelset's role, the wheel load's Hertz stiffness, the sensors' mounting
points, the support model, and the rail coupling to the bogie's other
wheelset when the evidence holds its channels) is assembled by
:meth:`~estimator.diagnosis.transfer.WheelsetBlocks.transfer` (memoised per
distinct value), and the band variance of ``T S_a Tᴴ``
(:mod:`estimator.diagnosis.evidence`), times the estimator's contact-filter
correction where it applies one, gives the estimate's level. A wheel's
roughness left in the estimate is removed in power (its spectrum
``L(λ) = level + slope·log₂(λ/0.1 m)`` dB re 1 µm per one-third-octave band).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from estimator.contact_filter import contact_gain
from estimator.diagnosis.evidence import Evidence
from estimator.diagnosis.state import FieldState
from estimator.diagnosis.transfer import interp_apply, interp_weights

__all__ = ["Evaluator", "MIN_LEVEL_SHARE"]

#: an estimate's band variance never falls below this share of its value when a wheel's roughness is removed
MIN_LEVEL_SHARE = 0.01
_MEMO_MAX = 4096


@dataclass(frozen=True, eq=False)
class Evaluator:
    """Evidence + the wheelset blocks + the nominal field model: band levels for any state.

    Attributes
    ----------
    evidence : Evidence
    blocks : dict
        Wheelset → :class:`~estimator.diagnosis.transfer.WheelsetBlocks`.
    base_trackform : callable
        Chainage → the line's trackform there (before any calibration).
    contact : ContactParameters
        The estimator's contact (the wheel load is the state's when it has one).
    contact_filter : bool
        The estimator undoes the contact patch's averaging (:func:`estimator.contact_filter.contact_gain`,
        its ``contact_filter`` option): the estimate's spectrum is multiplied by the squared gain at
        ``κ = f/v`` (the reference is the unfiltered rail).
    """

    evidence: Evidence
    blocks: dict
    base_trackform: object
    contact: object
    contact_filter: bool = False
    _memo: dict = field(default_factory=dict, repr=False)

    def semi_axis(self, state: FieldState) -> float:
        """The Hertz contact's semi-axis along the track [m] at the state's wheel load."""
        return float(self._hertz(state).semi_axis_x)

    def trackform_at(self, state: FieldState, x: float):
        key = ("tf", x, state.trackform_changes, state.support_spacing_m, state.loss_reference_hz)
        tf = self._memo.get(key)
        if tf is None:
            tf = self._memo[key] = self._trackform_at(state, x)
        return tf

    def _trackform_at(self, state: FieldState, x: float):
        tf = self.base_trackform(x)
        for ch in state.trackform_changes:
            if ch.from_m <= x <= ch.to_m:
                tf = ch.apply(tf)
        return state.line_wide(tf)

    def theta_at(self, state: FieldState, seg, role: str | None = None) -> tuple[float, float]:
        """Contact angles (vehicle sides) of the segment's wheelset, or of the wheelset of ``role`` beside it."""
        if seg.curve is None:
            return seg.theta
        got = {r: (gl, gr) for c, r, gl, gr in state.curve_angles if c == seg.curve}
        g = got.get(role or seg.role, got.get("any"))
        if g is None:
            return seg.theta
        gamma = dict(zip(("L", "R"), g))
        # vehicle sides: θ_L = −γ of the rail under the left wheel, θ_R = +γ of the rail under the right one
        return -gamma[seg.rails[0]], gamma[seg.rails[1]]

    def _hertz(self, state: FieldState):
        key = ("hertz", state.wheel_load_N)
        h = self._memo.get(key)
        if h is None:
            c = self.contact if state.wheel_load_N is None else replace(self.contact, wheel_load_N=state.wheel_load_N)
            h = self._memo[key] = c.contact()
        return h

    def stiffness(self, state: FieldState) -> float:
        return float(self._hertz(state).stiffness)

    def pieces(self, state: FieldState, seg) -> list[tuple[float, float]]:
        """``(share, chainage)`` of the parts of the segment under one trackform each.

        A trackform change whose end falls inside the segment splits it: the estimator (its line with the
        change) inverts each part with its own trackform, and the segment's band variance is the mean over its
        length of the parts' (a Welch spectrum is the mean of its windows' periodograms), so each part weighs
        by its share of the segment's length. The part's accelerations are the segment's (the evidence does
        not resolve them further). ``chainage`` is the part's middle (where its trackform is read).
        """
        a, b = seg.from_m, seg.to_m
        cuts = sorted({a, b} | {x for ch in state.trackform_changes for x in (ch.from_m, ch.to_m) if a < x < b})
        if len(cuts) == 2:
            return [(1.0, seg.centre_m)]
        out: dict = {}
        for lo, hi in zip(cuts[:-1], cuts[1:]):
            x = 0.5 * (lo + hi)
            tf = self.trackform_at(state, x)
            w, x0 = out.get(tf, (0.0, x))
            out[tf] = (w + (hi - lo) / (b - a), x0)
        return list(out.values())

    def transfer(self, state: FieldState, seg, at_m: float | None = None) -> np.ndarray:
        """The estimator's map from the segment's channels (``seg.S``'s rows) to the irregularity per side.

        ``(n_f, sides, m)``, or ``(n_f, sides, m + m')`` with the other wheelset's channels when the segment
        holds them (the rail coupling: :meth:`~estimator.diagnosis.transfer.WheelsetBlocks.coupled_transfer`).
        ``at_m``: the chainage whose trackform it uses (default the segment's centre; :meth:`pieces`).
        """
        bl = self.blocks[seg.wheelset]
        tf = self.trackform_at(state, seg.centre_m if at_m is None else at_m)
        th = self.theta_at(state, seg)
        th = (round(th[0], 6), round(th[1], 6))
        k = self.stiffness(state)
        offs = tuple(state.offset_of(c) for c in bl.channels)
        other = self.blocks.get(seg.other) if seg.other is not None else None
        offs_o = tuple(state.offset_of(c) for c in other.channels) if other is not None else ()
        wb = round(float(seg.wheelbase_m), 4) if other is not None else None
        th_o = None
        if other is not None:  # the other wheelset's forces along its own normals (its role's angles)
            th_o = self.theta_at(state, seg, "trailing" if seg.role == "leading" else "leading")
            th_o = (round(th_o[0], 6), round(th_o[1], 6))
        key = (seg.wheelset, tf, th, round(k, 3), offs, state.supports, seg.other, offs_o, wb, th_o)
        T = self._memo.get(key)
        if T is None:
            if len(self._memo) > _MEMO_MAX:
                # (not ``k``: that is the Hertz stiffness used below)
                for old in [m for m in self._memo if m[0] != "bands"]:
                    del self._memo[old]

            def arr(o):
                return np.array(o) if any(any(v) for v in o) else None

            if other is None:
                T = bl.transfer(tf, th, k, offsets=arr(offs), supports=state.supports)
            else:
                T = bl.coupled_transfer(other, tf, th, k, wb, offsets=arr(offs), offsets_other=arr(offs_o),
                                        supports=state.supports, theta_other=th_o)
            self._memo[key] = T
        return T

    def segment_variance(self, state: FieldState, si: int) -> np.ndarray:
        """The estimate's band variance (n_rails, n_bands of the segment) [m²]."""
        seg = self.evidence.segments[si]
        bl = self.blocks[seg.wheelset]
        bt = self.evidence.band_table
        key = ("bands", si)
        if key not in self._memo:
            # the frequency lines of each band (× df): the band integral is one matrix product
            W = np.zeros((seg.f.size, seg.bands.size))
            df = float(seg.f[1] - seg.f[0])
            for k, b in enumerate(seg.bands):
                W[(seg.f >= seg.speed_m_s / bt[b, 2]) & (seg.f < seg.speed_m_s / bt[b, 1]), k] = df
            used = np.flatnonzero(W.any(axis=1))
            # the segment's spectra on those lines and where they fall on the blocks' grid, kept with them
            self._memo[key] = (used, W[used], seg.S[used], interp_weights(bl.df, bl.f.size, seg.f[used]))
        used, W, S, at = self._memo[key]
        parts = self.pieces(state, seg)
        psd = 0.0
        for share, x in parts:
            T = interp_apply(self.transfer(state, seg, x), at)
            psd = psd + share * np.sum((T @ S) * np.conj(T), axis=-1).real  # diag(T S Tᴴ), (n_f, sides)
        if self.contact_filter:
            a = round(self.semi_axis(state), 9)
            gkey = ("gain", si, a)
            if gkey not in self._memo:
                self._memo[gkey] = contact_gain(seg.f[used] / seg.speed_m_s, a) ** 2
            psd = psd * self._memo[gkey][:, None]
        out = psd.T @ W
        if len(parts) > 1:
            out = out * self._mixture_correction(state, si, parts)
        for w, side, level, slope in state.wheel_roughness:
            if w != seg.wheelset:
                continue
            i = ("L", "R").index(side) if len(seg.rails) == 2 else 0
            lam = bt[seg.bands, 0]
            wheel = 1e-12 * 10 ** ((level + slope * np.log2(lam / 0.1)) / 10)
            out[i] = np.maximum(out[i] - wheel, MIN_LEVEL_SHARE * out[i])
        return out

    def _mixture_correction(self, state: FieldState, si: int, parts) -> np.ndarray:
        """Per rail and band: what the part-by-part inversion gives over what the shares' mix of it gives.

        The segment's spectrum mixes its parts', ``S = Σ_y w_y H_y P H_yᴴ``, and each part's inversion ``T_x``
        sees all of it: ``Σ_x w_x T_x S T_xᴴ`` carries the cross terms ``T_x H_y`` (x ≠ y), a bias that grows
        with the change (a stiffness ×2.5 reads +2 dB at half cover) and that the estimator, inverting each
        part's own accelerations, does not make. With the reference ``P`` (flat in each band, as in
        :meth:`inversion_floor`) and the parts' forward maps, the ratio of the part-by-part
        ``Σ_x w_x T_x H_x P H_xᴴ T_xᴴ`` to the mix ``Σ_x w_x Σ_y w_y T_x H_y P H_yᴴ T_xᴴ`` removes it (1 at
        full or no cover: the objective stays continuous as an end crosses a segment boundary). The own
        wheelset's channels only (the rail coupling's part is a small term of both).
        """
        seg = self.evidence.segments[si]
        bl = self.blocks[seg.wheelset]
        bt = self.evidence.band_table
        th = self.theta_at(state, seg)
        offs = np.array([state.offset_of(c) for c in bl.channels])
        k = self.stiffness(state)
        key = ("mix", si, tuple((round(w, 9), self.trackform_at(state, x)) for w, x in parts),
               (round(th[0], 6), round(th[1], 6)), round(k, 3), offs.tobytes(), state.supports)
        if key in self._memo:
            return self._memo[key]
        # the blocks' frequency lines inside the segment's bands (the products below only there)
        lines = np.flatnonzero((bl.f >= seg.speed_m_s / bt[seg.bands, 2].max())
                               & (bl.f < seg.speed_m_s / bt[seg.bands, 1].min()))
        Ts, Hs = [], []
        for _, x in parts:
            tf = self.trackform_at(state, x)
            hk = ("fwd", seg.wheelset, tf, (round(th[0], 6), round(th[1], 6)), round(k, 3), offs.tobytes(),
                  state.supports)
            if hk not in self._memo:
                self._memo[hk] = bl.forward(tf, th, k, offsets=offs, supports=state.supports)
            Hs.append(self._memo[hk][lines])
            Ts.append(self.transfer(state, seg, x)[lines, :, :len(bl.channels)])
        w = np.array([p[0] for p in parts])
        exact = sum(w[i] * np.abs(np.einsum("fim,fmj->fij", Ts[i], Hs[i])) ** 2 for i in range(len(parts)))
        mixed = sum(w[i] * w[j] * np.abs(np.einsum("fim,fmj->fij", Ts[i], Hs[j])) ** 2
                    for i in range(len(parts)) for j in range(len(parts)))
        f = bl.f[lines]
        out = np.ones((len(seg.rails), seg.bands.size))
        for kb, b in enumerate(seg.bands):
            sel = (f >= seg.speed_m_s / bt[b, 2]) & (f < seg.speed_m_s / bt[b, 1])
            p = np.nan_to_num(seg.ref_var[:, kb])
            if not sel.any() or not p.any():
                continue
            num, den = exact[sel].sum(axis=0) @ p, mixed[sel].sum(axis=0) @ p
            good = den > 0
            out[good, kb] = num[good] / den[good]
        self._memo[key] = out
        return out

    def inversion_floor(self, state: FieldState) -> list[np.ndarray]:
        """Per segment: the error [dB] the estimator makes even with the right model (its regularisation).

        The roughness the reference measured (flat within each band at its band variance) is sent through the
        model's own forward map ``H = B D⁻¹`` and back through ``T``: ``10 lg(Σ|T H|² P / Σ P)`` per rail and
        band. No effect can take the error below it.
        """
        out = []
        bt = self.evidence.band_table
        for si, seg in enumerate(self.evidence.segments):
            bl = self.blocks[seg.wheelset]
            tf = self.trackform_at(state, seg.centre_m)
            th = self.theta_at(state, seg)
            offs = [state.offset_of(c) for c in bl.channels]
            H = bl.forward(tf, th, self.stiffness(state), offsets=np.array(offs), supports=state.supports)
            T = self.transfer(state, seg)[:, :, :len(bl.channels)]  # the own channels' part: T of the wheelset
            R = np.abs(np.einsum("fim,fmj->fij", T, H)) ** 2  # (n_f, sides, sides) on the blocks' grid
            e = np.full((len(seg.rails), seg.bands.size), np.nan)
            for k, b in enumerate(seg.bands):
                sel = (bl.f >= seg.speed_m_s / bt[b, 2]) & (bl.f < seg.speed_m_s / bt[b, 1])
                if not sel.any():
                    continue
                p = np.nan_to_num(seg.ref_var[:, k]) / sel.sum()  # flat PSD per grid line
                est = R[sel].sum(axis=0) @ p
                with np.errstate(divide="ignore", invalid="ignore"):
                    e[:, k] = 10 * np.log10(est / (p * sel.sum()))
            out.append(e)
        return out

    def errors(self, state: FieldState, segments=None) -> list[np.ndarray]:
        """Per segment: level error ``10 lg(est/ref)`` [dB] (n_rails, n_bands; NaN where no reference)."""
        idx = range(len(self.evidence.segments)) if segments is None else segments
        out = []
        for si in idx:
            seg = self.evidence.segments[si]
            v = self.segment_variance(state, si)
            with np.errstate(divide="ignore", invalid="ignore"):
                out.append(10 * np.log10(v / seg.ref_var))
        return out


def summary_error(errs: list[np.ndarray], valid: list[np.ndarray]) -> tuple[float, int]:
    """RMS of the cell errors [dB] and the number of cells."""
    e = np.concatenate([x[m] for x, m in zip(errs, valid)]) if errs else np.zeros(0)
    return (float(np.sqrt(np.mean(e ** 2))) if e.size else math.nan), int(e.size)
