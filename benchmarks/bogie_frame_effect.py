"""What the bogie frame changes in the axlebox response, against the thesis's primary suspension to ground.

The estimator's wheelset hangs on the primary suspension of thesis Table 2.1 with the springs' other end on
the ground (thesis §2.3 neglects the bogie). The virtual line's trailer bogie has a rigid frame (2.6 t) on
those springs and on two air springs. This script solves the linearised wheelset–track–contact system of the
virtual line in the frequency domain (``tests/test_line_physics.coupled_oracle``: the two truth wheelsets,
the frame, the infinite continuously supported Timoshenko rail with the causal pads, the linearised Hertz
spring) twice — with the frame, and with the frame's mass and inertia multiplied by 10⁴ (a grounded primary
suspension) — and prints the ratio of the axlebox acceleration above the excited wheel, per unit roughness
under that wheel alone and under both wheels of the leading wheelset in phase.

A ratio above 0 dB is a response the estimator's model underestimates there, so its roughness estimate comes
out that much too high. Near the wheel-on-track resonance (P2, ~45 Hz) the primary dampers carry a noticeable
share of the damping, and the frame's inertia between them and the car body changes it.

    python benchmarks/bogie_frame_effect.py [--speed 15]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

FREQS_HZ = np.array([8.0, 10.0, 12.0, 15.0, 18.0, 22.0, 27.0, 32.0, 36.0, 40.0, 45.0, 50.0, 56.0, 63.0, 80.0,
                     100.0, 125.0, 160.0])


class _Grounded:
    """The oracle reads ``params`` and ``hertz`` only."""

    def __init__(self, params, hertz):
        self.params, self.hertz = params, hertz


def main(argv=None) -> int:
    from test_line_physics import build_vehicle, coupled_oracle, VehicleParameters

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=15.0, help="train speed [m/s] (the moving load on the rail)")
    a = ap.parse_args(argv)
    vehicle = build_vehicle(VehicleParameters(wheelset_scenario="control"))
    p = vehicle.params
    heavy = _Grounded(replace(p, frame_mass=p.frame_mass * 1e4, frame_inertia=tuple(1e4 * i for i in p.frame_inertia)),
                      vehicle.hertz)
    print(f"frame {p.frame_mass:g} kg, inertia {p.frame_inertia} kg m^2; primary stiffness {p.primary.stiffness} "
          f"N/m, damping {p.primary.damping} N s/m per axlebox; speed {a.speed:g} m/s")
    cases = {"one wheel (ws1 L)": [1, 0, 0, 0], "ws1 both wheels in phase": [1, 1, 0, 0]}
    ratios = {}
    for name, r in cases.items():
        _, with_frame = coupled_oracle(vehicle, FREQS_HZ, a.speed, np.array(r, complex))
        _, grounded = coupled_oracle(heavy, FREQS_HZ, a.speed, np.array(r, complex))
        ratios[name] = with_frame[:, 0] / grounded[:, 0]
    print(f"{'f [Hz]':>7} {'wavelength at speed':>20} " + " ".join(f"{n:>34}" for n in cases))
    for j, f in enumerate(FREQS_HZ):
        cells = " ".join(f"{20 * np.log10(abs(ratios[n][j])):+8.2f} dB {np.degrees(np.angle(ratios[n][j])):+6.1f} deg"
                         f"{'':>14}" for n in cases)
        print(f"{f:7.0f} {1e3 * a.speed / f:17.0f} mm {cells}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
