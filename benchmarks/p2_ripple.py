"""Where the estimate's gain ripple around the wheel-on-track resonance (P2) comes from, on the line's own oracle.

On straight 4 at cruise speed the day average's 300–1000 mm error repeats from run to run: a gain ripple of
about +1 dB at 34 Hz and −0.8 dB at 45 Hz around P2 (README, issue 14). This script separates two candidates with
the virtual line's frequency-domain oracle (``tests/test_line_physics.coupled_oracle``: the two truth wheelsets,
the bogie frame, the infinite continuously supported Timoshenko rail with the line's causal pads under the
moving loads, the linearised Hertz spring at the static load):

1. **The bogie frame**, which the estimator, like thesis §2.3, leaves out (its primary suspension ends on the
   ground). The oracle is solved with the 2.6 t frame and with the frame's mass and inertia ×10⁴ (a grounded
   suspension) *at the same contact stiffness*: a heavier frame would otherwise also load the wheels ×1400 and
   stiffen the linearised Hertz spring, which is not the frame's dynamics.
2. **The track's loss law.** The estimator's own transfer functions (the lab workflow's hybrid model of the
   control wheelset, design FE to 2 kHz; vertical model, rail coupling of the two wheelsets) are applied to the
   oracle's four axlebox accelerations, with the trackform of straight 4 under eq. 2.32 (constant loss
   factors) and under the causal layer law with the table's stiffness holding at 10 Hz, at the line's own
   reference (where its causal law's real part crosses the table value), at 146.5 Hz (the field diagnosis's
   fit on curve 1) and at 1 kHz. Estimate / truth is printed for roughness under one wheel and under both
   wheels of the leading wheelset.

    PYTHONPATH=. python benchmarks/p2_ripple.py [--speed 15]
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from line_laws import line_loss_reference_hz

sys.path.insert(0, str(Path(__file__).resolve().parent))

FRAME_FREQS_HZ = np.array([15.0, 20.0, 27.0, 32.0, 36.0, 40.0, 45.0, 50.0, 56.0, 63.0, 80.0, 100.0])
RIPPLE_FREQS_HZ = np.array([20.0, 25.0, 28.0, 32.0, 36.0, 40.0, 45.0, 50.0, 56.0, 63.0, 71.0, 80.0, 100.0])
CASES = {"one wheel (ws1 L)": [1, 0, 0, 0], "ws1 both wheels in phase": [1, 1, 0, 0]}
BOXES = ((0, 0), (0, 1), (1, 0), (1, 1))


class _Vehicle:
    """The oracle reads ``params`` and ``hertz`` only."""

    def __init__(self, params, hertz):
        self.params, self.hertz = params, hertz


def frame_table(vehicle, speed: float) -> None:
    from test_line_physics import coupled_oracle, static_wheel_load

    p = vehicle.params
    load = static_wheel_load(p)
    heavy = _Vehicle(replace(p, frame_mass=p.frame_mass * 1e4, frame_inertia=tuple(1e4 * i for i in p.frame_inertia)),
                     vehicle.hertz)
    print(f"1. bogie frame: {p.frame_mass:g} kg, inertia {p.frame_inertia} kg m^2; primary stiffness "
          f"{p.primary.stiffness} N/m, damping {p.primary.damping} N s/m per axlebox; both at the static wheel load "
          f"{load:.0f} N. Axlebox acceleration above the excited wheel, frame / grounded:")
    ratios = {}
    for name, r in CASES.items():
        _, with_frame = coupled_oracle(vehicle, FRAME_FREQS_HZ, speed, np.array(r, complex), wheel_load=load)
        _, grounded = coupled_oracle(heavy, FRAME_FREQS_HZ, speed, np.array(r, complex), wheel_load=load)
        ratios[name] = with_frame[:, 0] / grounded[:, 0]
    print(f"{'f [Hz]':>7} {'wavelength':>11} " + " ".join(f"{n:>28}" for n in CASES))
    for j, f in enumerate(FRAME_FREQS_HZ):
        cells = " ".join(f"{20 * np.log10(abs(ratios[n][j])):+14.3f} dB {np.degrees(np.angle(ratios[n][j])):+6.2f} deg"
                         for n in CASES)
        print(f"{f:7.0f} {1e3 * speed / f:8.0f} mm {cells}")


def ripple_table(vehicle, speed: float, campaign: Path, model_file: Path) -> None:
    from test_line_physics import coupled_oracle

    from estimator import EstimatorConfig, prepare
    from estimator.io import read_line

    line = read_line(campaign / "line.json")
    tf0 = next(t.trackform for t in line.trackforms if t.from_m <= 1450.0 <= t.to_m)
    refs = (None, 10.0, round(line_loss_reference_hz(), 1), 146.5, 1000.0)
    p = vehicle.params
    est = {}
    for ref in refs:
        fm = prepare(str(model_file), str(campaign / "sensors.csv"), trackform=replace(tf0, loss_reference_hz=ref),
                     config=EstimatorConfig(models=("vertical",)))
        z = fm.sensors[fm.sensors["direction"] == "z"]
        subs = [z[z["wheelset"] == w].reset_index(drop=True) for w in (1, 2)]
        t1, t2 = (fm.transfer("vertical", s, 1000.0, -1, (0.0, 0.0)) for s in subs)
        cross = fm.coupling(t1, t2, -1, p.wheelbase) @ t2.P
        idx = np.round(RIPPLE_FREQS_HZ / (t1.freqs_hz[1] - t1.freqs_hz[0])).astype(int)
        for name, r in CASES.items():
            _, a = coupled_oracle(vehicle, RIPPLE_FREQS_HZ, speed, np.array(r, complex), axleboxes=BOXES)
            # oracle boxes: ws1 L, ws1 R, ws2 L, ws2 R; the transfers' channels in their own order
            a1 = np.stack([a[:, 0] if s == "L" else a[:, 1] for s in subs[0]["side"]], axis=1)
            a2 = np.stack([a[:, 2] if s == "L" else a[:, 3] for s in subs[1]["side"]], axis=1)
            e = np.einsum("fsc,fc->fs", t1.T[idx], a1) + np.einsum("fsc,fc->fs", cross[idx], a2)
            est[(name, ref)] = e[:, 0]
    labels = ["eq. 2.32" if r is None else f"causal @ {r:g} Hz" for r in refs]
    print(f"\n2. the estimator's transfer functions ({model_file.name}, vertical, rail coupling) on the oracle's "
          f"accelerations; estimate / truth of the roughness under ws1 L [dB / deg] per track law of the "
          f"estimator (the line's own: causal @ {refs[2]:g} Hz)")
    for name in CASES:
        print(f"  {name}")
        print(f"{'f [Hz]':>7} " + " ".join(f"{lab:>16}" for lab in labels))
        for j, f in enumerate(RIPPLE_FREQS_HZ):
            print(f"{f:7.0f} " + " ".join(f"{20 * np.log10(abs(est[(name, r)][j])):+9.2f} "
                                           f"{np.degrees(np.angle(est[(name, r)][j])):+5.0f}" for r in refs))


def main(argv=None) -> int:
    from monitor_acceptance import AVERAGING, _model_file

    from lab_data.line.cache import line_campaign_dir
    from lab_data.line.vehicle import VehicleParameters, build_vehicle

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=15.0, help="train speed [m/s] (the moving load on the rail)")
    ap.add_argument("--work", default=str(Path.home() / ".cache" / "railmodal" / "p2_ripple"),
                    help="folder for the field model file (built once by the lab workflow)")
    a = ap.parse_args(argv)
    vehicle = build_vehicle(VehicleParameters(wheelset_scenario="control"))
    frame_table(vehicle, a.speed)
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    # the straight's averaging campaign of monitor_acceptance (its line and sensor table; cached after one run)
    campaign = line_campaign_dir("nominal", **{**AVERAGING, "section": (1260.0, 1640.0)})
    ripple_table(vehicle, a.speed, campaign, _model_file(work, 2000.0))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
