"""Benchmark: the vectorised robustness study (thesis §4.2) against a straightforward per-frequency loop.

Goal (issue 4): 1000 perturbed 3-channel vertical+lateral models over 4096
frequency lines in ≤ 2 s on 2 cores.

Two wheelset models: (1) the virtual lab's *design* FE export (free-free,
FE frequencies, 0.5 % damping, rigid-body modes below 1 Hz as the mass line)
at the contact points and axleboxes of ``points.csv`` — real modes, so the
loop peer can use the classical modal sum and both are compared on the same
models; (2) the in-service hybrid model (every FE mode kept, primary
suspension of Table 2.1 as a structural modification: complex modes), timed
for the vectorised study only.

The peer is what one would write first: per model, per frequency, build the
receptance matrices by the modal sum and solve with ``np.linalg.lstsq``.
It is timed on a few models and extrapolated linearly to 1000 (it is
linear in the number of models); both are run on those common models and
their mean/std compared.

Run: ``python benchmarks/bench_robustness.py [--models 1000] [--loop-models 3]``
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import argparse
import os
import time

import numpy as np
import pandas as pd

from fem_import import read
from lab_data.cache import campaign_dir
from receptance.contact import ContactParameters
from receptance.pole_residue import PoleResidues
from receptance.robustness import perturbation_factors, robustness_study
from receptance.track import track_receptance
from receptance.trackform import Trackform
from receptance.transfer import contact_normals

CONTACT = ("contact_L:y", "contact_L:z", "contact_R:y", "contact_R:z")
CHANNELS = ("axlebox_L:z", "axlebox_R:z", "axlebox_R:y")
THETA = (0.05, -0.05)
ZETA = 0.005


def design_model():
    """Modal data at the contact and axlebox points of the lab's design FE export."""
    d = campaign_dir("control")
    fe = read(d / "fe_design.uff")
    pts = pd.read_csv(d / "points.csv").set_index("name")
    labels, nodes, xyz, dirs = [], [], [], []
    for p in ("contact_L", "axlebox_L", "contact_R", "axlebox_R"):
        r = pts.loc[p]
        for ax, v in (("y", (0.0, 1.0, 0.0)), ("z", (0.0, 0.0, 1.0))):
            labels.append(f"{p}:{ax}")
            nodes.append(int(r.fe_node))
            xyz.append((r.x, r.y, r.z))
            dirs.append(v)
    phi = fe.at_points(nodes, np.array(xyz), np.array(dirs), names=labels)
    f = np.where(fe.freqs_hz < 1.0, 0.0, fe.freqs_hz)
    return f, phi, tuple(labels)


def loop_study(f_modes, phi, labels, freqs, fw, fz, n_models):
    """Per model, per frequency: receptances by the modal sum, forces by np.linalg.lstsq."""
    pos = {lab: i for i, lab in enumerate(labels)}
    flex = np.flatnonzero(f_modes > 0)
    rigid = np.flatnonzero(f_modes == 0)
    Pc = phi[[pos[c] for c in CONTACT]]
    Pa = phi[[pos[c] for c in CHANNELS]]
    nrm = contact_normals(*THETA)
    N = np.zeros((4, 2))
    N[0:2, 0] = nrm[0]
    N[2:4, 1] = nrm[1]
    ary = track_receptance(freqs, Trackform(), "lateral")
    arz = track_receptance(freqs, Trackform(), "vertical")
    kh = ContactParameters().stiffness()
    w0 = 2 * np.pi * f_modes[flex]

    def matrices(Om, w, z, k):
        h = 1.0 / (w**2 - Om**2 + 2j * z * w * Om)
        AW = (Pc[:, flex] * h) @ Pc[:, flex].T - Pc[:, rigid] @ Pc[:, rigid].T / Om**2
        AB = (Pa[:, flex] * h) @ Pc[:, flex].T - Pa[:, rigid] @ Pc[:, rigid].T / Om**2
        AR = np.diag([ary[k], arz[k], ary[k], arz[k]])
        D = N.T @ (AW + AR) @ N + np.eye(2) / kh
        return D, -Om**2 * AB @ N

    mags = np.zeros((n_models, 2, freqs.size))
    for k, fk in enumerate(freqs):
        Om = 2 * np.pi * fk
        D0, B0 = matrices(Om, w0, ZETA, k)
        a = B0 @ np.linalg.solve(D0, np.array([1.0, 0.0]))
        for p in range(n_models):
            D, B = matrices(Om, w0 * fw[p], ZETA * fz[p], k)
            F = np.linalg.lstsq(B, a, rcond=None)[0]
            mags[p, :, k] = np.abs(D @ F)
    return mags.mean(axis=0), mags.std(axis=0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=int, default=1000)
    ap.add_argument("--loop-models", type=int, default=3)
    ap.add_argument("--lines", type=int, default=4096)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)

    f_modes, phi, labels = design_model()
    pr = PoleResidues.from_modes(f_modes, ZETA, phi, phi[[labels.index(c) for c in CONTACT]], labels, CONTACT)
    freqs = np.linspace(500 / args.lines, 500, args.lines)
    n_pairs = int(np.count_nonzero(f_modes))
    kw = dict(amplitude=0.10, seed=0, models=("vertical_lateral",), theta_l=THETA[0], theta_r=THETA[1],
              lateral_channels=CHANNELS)
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:
        cpus = os.cpu_count()
    print(f"model: design FE export, {f_modes.size} modes ({n_pairs} flexible, {f_modes.size - n_pairs} rigid -> "
          f"mass line), zeta {ZETA}; vertical+lateral model, channels {list(CHANNELS)}, theta {THETA} rad")
    print(f"problem: {args.models} perturbed models x {freqs.size} lines (0-500 Hz), +-10 %; {cpus} CPU(s), "
          f"load average {os.getloadavg()[0]:.2f}")

    robustness_study(pr, freqs, n_models=4, **kw)  # warm-up (imports, BLAS)
    times = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        robustness_study(pr, freqs, n_models=args.models, **kw)
        times.append(time.perf_counter() - t0)
    t_vec = min(times)
    times1 = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        robustness_study(pr, freqs, n_models=args.models, workers=1, **kw)
        times1.append(time.perf_counter() - t0)

    n_loop = args.loop_models
    fw, fz = perturbation_factors(n_loop, n_pairs, 0.10, 0)
    t0 = time.perf_counter()
    m_loop, s_loop = loop_study(f_modes, phi, labels, freqs, fw, fz, n_loop)
    t_loop_few = time.perf_counter() - t0
    t_loop = t_loop_few / n_loop * args.models
    small = robustness_study(pr, freqs, n_models=n_loop, **kw)
    m_vec, s_vec = small.spread("vertical_lateral")
    dm = np.abs(m_vec - m_loop).max() / np.abs(m_loop).max()
    ds = np.abs(s_vec - s_loop).max() / np.abs(s_loop).max()

    print()
    print(f"{'method':<46}{'time [s]':>12}")
    print(f"{'vectorised robustness_study (best of ' + str(args.repeat) + ')':<46}{t_vec:>12.3f}"
          f"   runs: {', '.join(f'{t:.3f}' for t in times)}")
    print(f"{'vectorised, one worker thread (best of ' + str(args.repeat) + ')':<46}{min(times1):>12.3f}"
          f"   runs: {', '.join(f'{t:.3f}' for t in times1)}")
    print(f"{'per-frequency loop + np.linalg.lstsq':<46}{t_loop:>12.1f}"
          f"   EXTRAPOLATED from {n_loop} models ({t_loop_few:.2f} s) to {args.models}")
    print(f"speed ratio (loop / vectorised): {t_loop / t_vec:.0f}x")
    print(f"max difference on the {n_loop} common models: mean {dm:.2e}, std {ds:.2e} (relative to max)")
    print(f"goal <= 2 s for 1000 models x 4096 lines: {'met' if t_vec <= 2 else 'NOT met'}"
          + ("" if args.models == 1000 and args.lines == 4096 else " (different problem size)"))
    service = in_service_model()
    robustness_study(service, freqs, n_models=4, **kw)
    times_s = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        robustness_study(service, freqs, n_models=args.models, **kw)
        times_s.append(time.perf_counter() - t0)
    print(f"{'in-service hybrid model, vectorised (best of ' + str(args.repeat) + ')':<46}{min(times_s):>12.3f}"
          f"   runs: {', '.join(f'{t:.3f}' for t in times_s)}  (complex modes: suspension-coupled pairs)")
    print(f"goal on the in-service model: {'met' if min(times_s) <= 2 else 'NOT met'}")
    return 0


def in_service_model():
    """Every design FE mode (FE frequencies, 0.5 % damping) on the primary suspension (Table 2.1)."""
    from receptance.dofs import read_points
    from receptance.hybrid import hybrid_model
    from receptance.modification import PrimarySuspension

    d = campaign_dir("control")
    fe = read(d / "fe_design.uff")
    elastic = np.flatnonzero(fe.freqs_hz > 1.0)
    table = pd.DataFrame({"test_mode": elastic + 1, "f_test_hz": fe.freqs_hz[elastic],
                          "fe_modes": [str(j + 1) for j in elastic], "zeta": ZETA})
    model = hybrid_model(fe, table, points=read_points(d / "points.csv"))
    return model.with_modification(PrimarySuspension())


if __name__ == "__main__":
    raise SystemExit(main())
