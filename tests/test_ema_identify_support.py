"""Helpers for the identification tests (no tests here).

* :func:`lab_h1` — measured H1 accelerances of a virtual-lab campaign, made
  independently of ``ema``'s input side: pyuff reads the UFF58 time
  histories, the manifest's double hits and clipped (hit, node) pairs are
  dropped, the same exponential window ``exp(-a (t - t_hit))`` multiplies force
  and responses (``t_hit`` = first force sample above 5 % of its peak) and
  ``H1 = sum conj(F) A / sum |F|^2`` over the accepted hits (thesis eq. 3.2).
* :func:`modal_truth` — the manifest's modal truth of a setup as a
  :class:`lab_data.hammer.ModalTruth` (the FRF oracle).
* :func:`match_to_truth` — acceptance bookkeeping: identified modes versus
  the manifest's truth modes.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pyuff

from ema.frf import FrequencyResponse
from ema.lsfd import mac
from lab_data.cache import campaign_dir
from lab_data.hammer import ModalTruth

BAND = (10.0, 500.0)


@functools.lru_cache(maxsize=None)
def manifest(scenario: str) -> dict:
    return json.loads((campaign_dir(scenario) / "truth.json").read_text())


@functools.lru_cache(maxsize=None)
def lab_h1(scenario: str, setup: str, decay: float = 2.0, band: tuple[float, float] = BAND) -> FrequencyResponse:
    """Windowed H1 of a lab setup from the raw UFF58 records (independent of ema's reader)."""
    d = campaign_dir(scenario)
    st = manifest(scenario)["setups"][setup]
    ch = pd.read_csv(d / f"{setup}_channels.csv")
    records: dict[tuple[int, int], np.ndarray] = {}
    dt = None
    for s in pyuff.UFF(str(d / f"{setup}.uff")).read_sets():
        records[(int(s["ver_num"]), int(s["rsp_node"]))] = np.asarray(s["data"], float)
        dt = float(s["abscissa_inc"])
    drop_hits = set(st["double_hits"])
    clipped = {(c["hit"], c["node"]) for c in st["clipped"]}
    acc = ch[ch["quantity"] == "acceleration"].reset_index(drop=True)
    force_node = int(ch.loc[ch["quantity"] == "force", "node"].iloc[0])
    hits = sorted({h for h, _ in records})
    n = next(iter(records.values())).size
    t = np.arange(n) * dt
    sfa = np.zeros((len(acc), n // 2 + 1), complex)
    sff = np.zeros((len(acc), n // 2 + 1))
    for h in hits:
        if h in drop_hits:
            continue
        f = records[(h, force_node)]
        t_hit = t[np.argmax(np.abs(f) > 0.05 * np.abs(f).max())]
        w = np.exp(-decay * (t - t_hit))
        F = np.fft.rfft(f * w)
        for j, node in enumerate(acc["node"]):
            if (h, int(node)) in clipped:
                continue
            A = np.fft.rfft(records[(h, int(node))] * w)
            sfa[j] += np.conj(F) * A
            sff[j] += np.abs(F) ** 2
    freqs = np.fft.rfftfreq(n, dt)
    sel = (freqs >= band[0]) & (freqs <= band[1])
    return FrequencyResponse(
        freqs[sel], (sfa / sff)[:, None, sel], tuple(acc["name"]), ("hammer",), quantity="accelerance",
        channels=acc, exp_window_decay=decay, history=(f"test H1, exp window {decay} 1/s",),
    )


def modal_truth(setup_manifest: dict) -> ModalTruth:
    ms = setup_manifest["modes"]
    return ModalTruth(
        [m["f_hz"] for m in ms], [m["zeta"] for m in ms], [m["input_shape"] for m in ms],
        np.array([m["shapes"] for m in ms], float).T,
    )


@dataclass
class Match:
    worst_df: float = 0.0
    worst_dzeta: float = 0.0
    worst_mac: float = 1.0
    missed: list | None = None
    spurious: list | None = None
    rows: list | None = None


def match_to_truth(modes, setup_manifest: dict, band=BAND, f_tol_spurious=0.005) -> Match:
    """Compare identified modes with the truth (observable modes must be found; nothing spurious).

    An observable truth mode is found by the identified mode that maximises
    MAC among those within 0.5 % in frequency; the relative errors of f and
    zeta and the MAC (truth shapes are real) are recorded.  An identified mode
    is spurious if no truth mode at all lies within ``f_tol_spurious``.
    """
    truth = [m for m in setup_manifest["modes"] if m["f_hz"] > 0]
    out = Match(missed=[], spurious=[], rows=[])
    shapes = modes.shapes
    for m in truth:
        if not (m["observable"] and band[0] <= m["f_hz"] <= band[1]):
            continue
        cand = np.flatnonzero(np.abs(modes.freqs_hz - m["f_hz"]) <= 0.005 * m["f_hz"])
        if cand.size == 0:
            out.missed.append((m["id"], m["f_hz"], m["description"]))
            continue
        macs = [float(mac(shapes[:, i], np.array(m["shapes"]))[0, 0]) for i in cand]
        i = int(cand[int(np.argmax(macs))])
        df = (modes.freqs_hz[i] - m["f_hz"]) / m["f_hz"]
        dz = (modes.zeta[i] - m["zeta"]) / m["zeta"]
        out.rows.append((m["f_hz"], df, dz, max(macs)))
        out.worst_df = max(out.worst_df, abs(df))
        out.worst_dzeta = max(out.worst_dzeta, abs(dz))
        out.worst_mac = min(out.worst_mac, max(macs))
    tf = np.array([m["f_hz"] for m in truth])
    for f in modes.freqs_hz:
        if not np.any(np.abs(tf - f) <= f_tol_spurious * f):
            out.spurious.append(float(f))
    return out


def assert_acceptance(m: Match, label: str) -> None:
    """Issue 3's identification acceptance: every observable truth mode found, none spurious,
    |df|/f <= 0.05 %, |dzeta|/zeta <= 10 % (after the window correction), MAC >= 0.99."""
    assert not m.missed, f"{label}: observable truth modes not identified: {m.missed}"
    assert not m.spurious, f"{label}: spurious modes (no truth mode within 0.5 %): {m.spurious}"
    assert m.worst_df <= 5e-4, f"{label}: |df|/f = {100 * m.worst_df:.5f} %"
    assert m.worst_dzeta <= 0.10, f"{label}: |dzeta|/zeta = {100 * m.worst_dzeta:.3f} %"
    assert m.worst_mac >= 0.99, f"{label}: MAC = {m.worst_mac:.6f}"
