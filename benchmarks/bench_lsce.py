"""LSCE with stabilisation: railmodal's ``ema`` versus sdypy-EMA, side by side (goal: >= 20x faster, <= 2 s).

Run: python benchmarks/bench_lsce.py [--max-order 100] [--scenario control] [--setup flexural]
(needs the optional extra: ``pip install -e .[bench]`` -> sdypy-EMA).

Data: the virtual lab's hammer test (default: control campaign, flexural
setup, 29 accelerometers), read, screened and turned into H1 accelerances
with the toolkit's own input side (``ema.read_hammer``, ``ema.screen_hits``,
``ema.estimate_frf``; exponential window chosen automatically), lines
0-500 Hz every 0.25 Hz.  Both estimators receive the same complex array.

* railmodal: ``ema.lsce`` on 10-500 Hz (zoomed, order = number of poles in
  the band, orders 1..max) + ``ema.stabilisation_diagram`` (frequency,
  damping and MAC stability with quick LS shapes for every order), and the
  whole ``ema.identify`` (automatic selection, refinement, LSFD) for reference.
* sdypy-EMA: ``Model(frf, freq, lower=0, upper=500, pol_order_high=max)``
  and ``get_poles(method='lsce')`` (poles only, no stability flags).
  ``lower=0`` because its LSCE mis-scales frequencies when ``lower > 0`` (it
  keeps the sampling interval of the full band after cutting the FRF); its
  order ``n`` means ``2n`` real AR coefficients, i.e. ``n`` pole pairs over
  0-500 Hz.

Accuracy against the truth manifest: for every observable truth mode the
pole of the *highest order* nearest in frequency, after the same
exponential-window correction ``s = s_w + a`` for both methods; printed as
Delta f [%] and Delta zeta [%] (relative).
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import argparse
import json
import logging
import time

import numpy as np

import ema
from lab_data.cache import campaign_dir


def _nearest(poles: np.ndarray, f_true: float) -> complex:
    poles = poles[poles.imag > 0]
    fr = np.abs(poles) / (2 * np.pi)
    return complex(poles[np.argmin(np.abs(fr - f_true))])


def _errors(pole: complex, f_true: float, z_true: float) -> tuple[float, float]:
    f = abs(pole) / (2 * np.pi)
    z = -pole.real / abs(pole)
    return 100 * (f - f_true) / f_true, 100 * (z - z_true) / z_true


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="control")
    ap.add_argument("--setup", default="flexural")
    ap.add_argument("--max-order", type=int, default=100)
    ap.add_argument("--skip-sdypy", action="store_true", help="time railmodal only")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)

    d = campaign_dir(args.scenario)
    truth = json.loads((d / "truth.json").read_text())["setups"][args.setup]
    test = ema.read_hammer(d / f"{args.setup}.uff", d / f"{args.setup}_channels.csv")
    frf0 = ema.estimate_frf(test, screening=ema.screen_hits(test), band_hz=(0.0, 500.0))
    a = frf0.exp_window_decay
    frf = frf0.select(band_hz=(10.0, 500.0))
    modes = [m for m in truth["modes"] if m["observable"] and 10 <= m["f_hz"] <= 500]
    print(f"{args.scenario}/{args.setup}: {frf.n_out} channels, {frf.freqs_hz.size} lines 10-500 Hz, "
          f"exponential window a = {a:.3f} 1/s, max order {args.max_order}, "
          f"{len(modes)} observable truth modes")

    # ---------------------------------------------------------------- railmodal
    ema.lsce(frf, max_order=10)  # warm-up (imports, BLAS threads)
    t0 = time.perf_counter()
    sweep = ema.lsce(frf, max_order=args.max_order)
    t1 = time.perf_counter()
    diagram = ema.stabilisation_diagram(sweep, frf)
    t2 = time.perf_counter()
    ident = ema.identify(frf, band_hz=(10.0, 500.0), max_order=args.max_order)
    t3 = time.perf_counter()
    ours_top = sweep.poles(len(sweep.orders) - 1)
    t_ours = t2 - t0

    # ---------------------------------------------------------------- sdypy-EMA
    t_sdy = np.nan
    sdy_top = None
    if not args.skip_sdypy:
        from sdypy import EMA

        H = np.array(frf0.data[:, 0, :])
        H[~np.isfinite(H)] = 0.0  # pyFRF-style H1 has NaN at 0 Hz; ours has not, keep the guard
        model = EMA.Model(frf=H, freq=frf0.freqs_hz, lower=0, upper=500, pol_order_high=args.max_order,
                          frf_form="accelerance")
        t4 = time.perf_counter()
        model.get_poles(method="lsce", show_progress=False)
        t_sdy = time.perf_counter() - t4
        sdy_top = np.asarray(model.all_poles[-1]) + a

    # ---------------------------------------------------------------- report
    print()
    print(f"{'':34s} {'wall [s]':>9s}")
    print(f"{'railmodal lsce (orders 1..max)':34s} {t1 - t0:9.3f}")
    print(f"{'railmodal lsce + stabilisation':34s} {t_ours:9.3f}")
    print(f"{'railmodal identify (everything)':34s} {t3 - t2:9.3f}")
    if not args.skip_sdypy:
        print(f"{'sdypy-EMA get_poles(lsce)':34s} {t_sdy:9.3f}")
        print(f"speed-up (sdypy / railmodal lsce + stabilisation): {t_sdy / t_ours:.1f}x")
    print()
    head = f"{'truth f [Hz]':>12s} {'zeta':>8s} | {'ours LSCE top order':>22s} | {'ours identify':>22s}"
    if sdy_top is not None:
        head += f" | {'sdypy LSCE top order':>22s}"
    print(head)
    print(f"{'':21s} | {'df %':>10s} {'dzeta %':>11s} | {'df %':>10s} {'dzeta %':>11s}"
          + (f" | {'df %':>10s} {'dzeta %':>11s}" if sdy_top is not None else ""))
    worst = {"ours": [0.0, 0.0], "ident": [0.0, 0.0], "sdy": [0.0, 0.0]}
    errs: dict[str, list] = {"ours": [], "ident": [], "sdy": []}
    for m in modes:
        f, z = m["f_hz"], m["zeta"]
        row = f"{f:12.3f} {z:8.5f} |"
        for key, poles in (("ours", ours_top), ("ident", ident.modes.poles), ("sdy", sdy_top)):
            if poles is None:
                continue
            df, dz = _errors(_nearest(np.asarray(poles), f), f, z)
            worst[key] = [max(worst[key][0], abs(df)), max(worst[key][1], abs(dz))]
            errs[key].append((abs(df), abs(dz)))
            row += f" {df:+10.4f} {dz:+11.3f} |"
        print(row.rstrip("|"))
    print(f"{'worst |error|':>21s} | {worst['ours'][0]:10.4f} {worst['ours'][1]:11.3f} | "
          f"{worst['ident'][0]:10.4f} {worst['ident'][1]:11.3f}"
          + (f" | {worst['sdy'][0]:10.4f} {worst['sdy'][1]:11.3f}" if sdy_top is not None else ""))
    med = {k: np.median(np.array(v), axis=0) if v else (np.nan, np.nan) for k, v in errs.items()}
    print(f"{'median |error|':>21s} | {med['ours'][0]:10.4f} {med['ours'][1]:11.3f} | "
          f"{med['ident'][0]:10.4f} {med['ident'][1]:11.3f}"
          + (f" | {med['sdy'][0]:10.4f} {med['sdy'][1]:11.3f}" if sdy_top is not None else ""))
    print(f"\nstable poles in the diagram: {int(diagram.stable.sum())} of {len(diagram)}; "
          f"identified modes: {', '.join(f'{x:.2f}' for x in ident.modes.freqs_hz)} Hz")


if __name__ == "__main__":
    main()
