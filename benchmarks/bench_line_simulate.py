"""Virtual line: time of one station-to-station passage of the dynamics core, beside the goal.

Goal (issue 12): one 1.5 km run (ATO speed profile, about 2 min of travel) simulated in ≤ 30 s on one
core; numba compilation reported apart (it is cached on disk after the first run). The passage is the
default line (:func:`lab_data.line.geometry.default_line`, 1.64 km between the stations), forward, with
its ATO profile, curve contact angles, 4 % support scatter and a broadband rail roughness of a few µm;
the wheelset is the lab's ``bearing`` truth. CPU time of the simulating process is printed beside the
wall time (the machine is shared).

    python benchmarks/bench_line_simulate.py [--scenario bearing] [--seconds N]
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

GOAL_RUN_S = 30.0


def passage_inputs(seconds: float | None, dt: float):
    """Per-step inputs of a forward run over the default line (roughness: 3 µm RMS, 25 mm – 2 m)."""
    from scipy.signal import butter, sosfiltfilt

    from lab_data.line.curving import rail_contact_angles, thesis_angles
    from lab_data.line.dynamics import PassageInput, SensorPoint
    from lab_data.line.geometry import cant_angle, curvature, default_line
    from lab_data.line.operation import ato_profile
    from lab_data.line.track import TrackLayout, milano_modificato

    line = default_line()
    prof = ato_profile(line, "forward")
    t_end = prof.duration if seconds is None else min(seconds, prof.duration)
    t = np.arange(0.0, t_end, dt)
    s, v, _ = prof.at(t)
    n = t.size
    wheel_s = s[None, :] + np.array([1.05, 1.05, -1.05, -1.05])[:, None]
    dx = 1e-3
    x = np.arange(-30.0, line.length_m + 30.0, dx)
    sos = butter(3, [1 / 2.0, 1 / 0.025], btype="band", fs=1 / dx, output="sos")
    rng = np.random.default_rng(5)
    rails = [sosfiltfilt(sos, rng.standard_normal(x.size)) for _ in range(2)]
    rails = [3e-6 * r / r.std() for r in rails]
    rough = np.stack([np.interp(wheel_s[w], x, rails[w % 2]) for w in range(4)])
    theta = np.zeros((4, n))
    for k, lead in ((0, True), (1, False)):
        g_l, g_r = rail_contact_angles(line, wheel_s[2 * k], v, np.full(n, lead))
        theta[2 * k], theta[2 * k + 1] = thesis_angles(g_l, g_r)
    chain = np.arange(0.375, line.length_m, 0.75)
    rng2 = np.random.default_rng(6)
    factors = {name: 1 + np.clip(rng2.normal(0, 0.04, (2, chain.size)), -0.12, 0.12)
               for name in ("pad_stiffness_z", "pad_stiffness_y", "subplate_stiffness_z", "subplate_stiffness_y")}
    layout = TrackLayout(chain, factors, milano_modificato())
    sensors = (SensorPoint(1, "L", "z", (0.01, -0.97, 0.0)), SensorPoint(1, "R", "z", (0.01, 0.97, 0.0)),
               SensorPoint(1, "R", "y", (0.0, 1.05, 0.0)), SensorPoint(2, "L", "z", (-0.01, -0.97, 0.0)),
               SensorPoint(2, "R", "z", (-0.01, 0.97, 0.0)), SensorPoint(2, "R", "y", (0.0, 1.05, 0.0)))
    inp = PassageInput(dt, s, 1, "normal", rough, theta, curvature(line, s), cant_angle(line, s), sensors, speed=v)
    return layout, inp, float(s[-1] - s[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="bearing", help="lab wheelset scenario (default bearing)")
    ap.add_argument("--seconds", type=float, default=None, help="simulate only the first N s of the run")
    args = ap.parse_args()

    from lab_data.line.dynamics import DEFAULT_DT, compile_kernels, simulate_passage
    from lab_data.line.vehicle import VehicleParameters, build_vehicle

    t0 = time.perf_counter()
    vehicle = build_vehicle(VehicleParameters(wheelset_scenario=args.scenario))
    t_vehicle = time.perf_counter() - t0
    t_compile = compile_kernels(vehicle)
    layout, inp, dist = passage_inputs(args.seconds, DEFAULT_DT)
    w0, c0 = time.perf_counter(), time.process_time()
    res = simulate_passage(vehicle, layout, inp)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    n = inp.n_steps
    print(f"vehicle build ({args.scenario}, cached truth FE)    {t_vehicle:8.2f} s")
    print(f"numba compile / cache load                  {t_compile:8.2f} s")
    print(f"passage: {dist:.0f} m, {n * DEFAULT_DT:.1f} s of travel, {n} steps of {DEFAULT_DT * 1e6:.1f} µs")
    print(f"  setup (track ring, statics)               {res.timings_s['setup']:8.2f} s")
    print(f"  time stepping  wall {res.timings_s['kernel']:8.2f} s   cpu {res.timings_s['kernel_cpu']:8.2f} s   "
          f"({res.timings_s['kernel_cpu'] / n * 1e6:.1f} µs/step cpu)")
    print(f"one run          wall {wall:8.2f} s   cpu {cpu:8.2f} s   goal <= {GOAL_RUN_S:.0f} s   "
          f"{'OK' if cpu <= GOAL_RUN_S else 'OVER'} (cpu)")
    print(f"contact lost in {int(res.contact_lost.any(axis=0).sum())} steps; axlebox z RMS "
          f"{np.sqrt(np.mean(res.acceleration[0] ** 2)):.2f} m/s^2")


if __name__ == "__main__":
    main()
