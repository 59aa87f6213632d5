"""The compiled time-stepping loop of :mod:`lab_data.line.dynamics` (numba, cached on disk).

Array layout (all C-contiguous, float64): rail/direction index ``rd = 2 rail + d`` (rail 0 = L, 1 = R;
d 0 = vertical z, 1 = lateral y); rail modes split into cosine and sine blocks ``[rd, n]``, harmonic
``n = 0..N`` (the sine mode of harmonic 0 does not exist and stays zero); supports ``[rd, slot]``;
vehicle complex modes split into real and imaginary parts ``[m]``. The algorithm is the one of the
:mod:`lab_data.line.dynamics` docstring; the comments here only say how the arrays implement it.

Speed (before tuning, about half of a step's time was in the supports, a quarter in the vehicle modes): numba
cannot tell LLVM that two arrays do not overlap, and LLVM gives up vectorising a loop that writes several
arrays (too many run-time overlap checks); the state updates are therefore written one array per loop, which LLVM
vectorises. The FFT does two radix-2 stages per pass in registers and takes its input in bit-reversed order.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["passage_kernel", "assign_slot", "supports_step", "fft_tables", "fft_inplace", "fft_butterflies",
           "N_PAR"]


def fft_tables(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bit-reversal permutation and per-stage twiddles of a radix-2 FFT of length n.

    Stage ``s`` (butterfly half-width ``h = 2**s``) uses ``cos(2πk/2h), sin(2πk/2h)``, k < h, stored from
    index ``h − 1`` of the flat tables (contiguous per stage, so the inner butterfly loop reads them in order).
    """
    bits = int(np.log2(n))
    bitrev = np.array([int(format(i, f"0{bits}b")[::-1], 2) for i in range(n)], dtype=np.int64)
    wr = np.empty(max(n - 1, 1))
    wi = np.empty(max(n - 1, 1))
    half = 1
    while half < n:
        k = np.arange(half)
        wr[half - 1:2 * half - 1] = np.cos(2 * np.pi * k / (2 * half))
        wi[half - 1:2 * half - 1] = np.sin(2 * np.pi * k / (2 * half))
        half *= 2
    return bitrev, wr, wi


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def fft_butterflies(re, im, inverse, wr, wi):
    """Radix-2 decimation-in-time butterflies of an input already in bit-reversed order (output natural).

    ``inverse`` uses e^{+i...}; no 1/n scaling. Two consecutive stages are done together on four points
    held in registers (a radix-4 pass made of the same radix-2 butterflies and twiddles, so the result is
    the radix-2 one, with half the memory traffic); a last odd stage is done alone.
    """
    n = re.size
    sgn = 1.0 if inverse else -1.0
    h = 1
    while h < n:
        if 4 * h <= n:
            o1 = h - 1
            o2 = 2 * h - 1
            for start in range(0, n, 4 * h):
                for k in range(h):
                    i0 = start + k
                    i1 = i0 + h
                    i2 = i1 + h
                    i3 = i2 + h
                    r0, m0, r1, m1 = re[i0], im[i0], re[i1], im[i1]
                    r2, m2, r3, m3 = re[i2], im[i2], re[i3], im[i3]
                    # stage of half-width h: pairs (0, 1) and (2, 3), twiddle k of that stage
                    c = wr[o1 + k]
                    d = sgn * wi[o1 + k]
                    tr = c * r1 - d * m1
                    ti = c * m1 + d * r1
                    r1, m1, r0, m0 = r0 - tr, m0 - ti, r0 + tr, m0 + ti
                    tr = c * r3 - d * m3
                    ti = c * m3 + d * r3
                    r3, m3, r2, m2 = r2 - tr, m2 - ti, r2 + tr, m2 + ti
                    # stage of half-width 2h: pairs (0, 2) with twiddle k, (1, 3) with twiddle k + h
                    c = wr[o2 + k]
                    d = sgn * wi[o2 + k]
                    tr = c * r2 - d * m2
                    ti = c * m2 + d * r2
                    re[i2] = r0 - tr
                    im[i2] = m0 - ti
                    re[i0] = r0 + tr
                    im[i0] = m0 + ti
                    c = wr[o2 + k + h]
                    d = sgn * wi[o2 + k + h]
                    tr = c * r3 - d * m3
                    ti = c * m3 + d * r3
                    re[i3] = r1 - tr
                    im[i3] = m1 - ti
                    re[i1] = r1 + tr
                    im[i1] = m1 + ti
            h *= 4
        else:
            o1 = h - 1
            for start in range(0, n, 2 * h):
                for k in range(h):
                    a = start + k
                    b = a + h
                    c = wr[o1 + k]
                    d = sgn * wi[o1 + k]
                    tr = c * re[b] - d * im[b]
                    ti = c * im[b] + d * re[b]
                    re[b] = re[a] - tr
                    im[b] = im[a] - ti
                    re[a] += tr
                    im[a] += ti
            h *= 2


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def fft_inplace(re, im, inverse, bitrev, wr, wi):
    """In-place radix-2 FFT from :func:`fft_tables`; ``inverse`` uses e^{+i...} and no 1/n scaling."""
    n = re.size
    for i in range(n):
        j = bitrev[i]
        if j > i:
            re[i], re[j] = re[j], re[i]
            im[i], im[j] = im[j], im[i]
    fft_butterflies(re, im, inverse, wr, wi)


#: Rows of ``par[rd, :, slot]``.
P_KP, P_CP, P_KS, P_CS, P_M4, P_M, P_AP, P_APS, P_INVS, P_D, P_INVDEN, P_CF = range(12)
N_PAR = 12


@numba.njit(cache=True)
def assign_slot(rd, i, col, table, par, fac, kb_unit, tau, dt, g0, Cf):
    """Give slot ``i`` of ``rd`` the parameters of layout column ``col`` and precompute its step constants.

    ``table[rd, :, col]`` = (pad k, pad c, pad η, plate mass, subplate k, subplate c, subplate η);
    ``Cf`` is the rail's within-step compliance at the slot. ``fac[rd, layer, b, i]`` is the Maxwell
    branch factor ``k_b τ_b (1 − e^{−h/τ_b}) / h`` (exact for a constant deformation rate over the step).
    """
    kp = table[rd, 0, col]
    cp = table[rd, 1, col]
    eta_p = table[rd, 2, col]
    m = table[rd, 3, col]
    ks = table[rd, 4, col]
    cs = table[rd, 5, col]
    eta_s = table[rd, 6, col]
    kp_lt = kp * (1.0 + eta_p * g0)
    ks_lt = ks * (1.0 + eta_s * g0)
    # the pad dashpot acts on the deformation rate averaged over the step (a Maxwell branch with τ → 0),
    # consistent with the rail's first-order-hold update; the plate's own dashpot is trapezoidal
    Ap = kp_lt + cp / dt
    As = ks_lt + 2.0 * cs / dt
    for b in range(kb_unit.size):
        E = np.exp(-dt / tau[b])
        fac[rd, 0, b, i] = kp * eta_p * kb_unit[b] * tau[b] * (1.0 - E) / dt
        fac[rd, 1, b, i] = ks * eta_s * kb_unit[b] * tau[b] * (1.0 - E) / dt
        Ap += fac[rd, 0, b, i]
        As += fac[rd, 1, b, i]
    Am = 4.0 * m / (dt * dt)
    S = Am + Ap + As
    D = Ap * (S - Ap) / S
    par[rd, P_KP, i] = kp_lt
    par[rd, P_CP, i] = cp
    par[rd, P_KS, i] = ks_lt
    par[rd, P_CS, i] = cs
    par[rd, P_M4, i] = 4.0 * m / dt
    par[rd, P_M, i] = m
    par[rd, P_AP, i] = Ap
    par[rd, P_APS, i] = Ap / S
    par[rd, P_INVS, i] = 1.0 / S
    par[rd, P_D, i] = D
    par[rd, P_INVDEN, i] = 1.0 / (1.0 + D * Cf)
    par[rd, P_CF, i] = Cf


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def supports_step(rd, n, U, f, dt, sup, pb, sb, par, Eb, fac, du, dz):
    """Implicit step of slots ``0..n-1`` of ``rd`` (trapezoidal plate, exponential Maxwell branches: exactly four).

    ``U[i]`` is the rail's displacement at slot i at the end of the step without the slot's own force;
    the force on the rail goes to ``f[i]``. ``sup[rd, k, i]``: k = 0 rail displacement u, 1 plate z, 2 plate
    velocity, 3 plate acceleration. The pad pulls rail and plate together
    with ``T_p = k_p (u − z) + c_p Δ(u − z)/h + Σ p_b``, the subplate holds the plate with
    ``T_s = k_s z + c_s ż + Σ s_b``; the plate's ``m z̈ = T_p − T_s`` at the end of the step, with the
    trapezoidal ``ż, z̈`` and the branches' exponential update, gives ``Δz`` linear in ``Δu`` and the
    rail force ``f = −T_p`` linear in ``U`` (closed form).

    ``du``, ``dz`` (length ≥ n) are scratch buffers for the increments: the force is solved slot by slot,
    then each state row is updated in its own loop (loops that write one array are vectorised).
    """
    c2 = 2.0 / dt
    c4 = 4.0 / (dt * dt)
    e0, e1, e2, e3 = Eb[0], Eb[1], Eb[2], Eb[3]
    for i in range(n):
        u = sup[rd, 0, i]
        z = sup[rd, 1, i]
        zd = sup[rd, 2, i]
        zdd = sup[rd, 3, i]
        Tp0 = par[rd, P_KP, i] * (u - z)
        Ts0 = par[rd, P_KS, i] * z - par[rd, P_CS, i] * zd
        Tp0 += e0 * pb[rd, 0, i] + e1 * pb[rd, 1, i] + e2 * pb[rd, 2, i] + e3 * pb[rd, 3, i]
        Ts0 += e0 * sb[rd, 0, i] + e1 * sb[rd, 1, i] + e2 * sb[rd, 2, i] + e3 * sb[rd, 3, i]
        M0 = -(par[rd, P_M4, i] * zd + par[rd, P_M, i] * zdd)
        R0 = Tp0 - Ts0 - M0
        g = Tp0 - par[rd, P_APS, i] * R0
        fi = -(g + par[rd, P_D, i] * (U[i] - u)) * par[rd, P_INVDEN, i]
        dui = U[i] + par[rd, P_CF, i] * fi - u
        f[i] = fi
        du[i] = dui
        dz[i] = (par[rd, P_AP, i] * dui + R0) * par[rd, P_INVS, i]
    for b in range(4):
        e = Eb[b]
        for i in range(n):
            pb[rd, b, i] = e * pb[rd, b, i] + fac[rd, 0, b, i] * (du[i] - dz[i])
        for i in range(n):
            sb[rd, b, i] = e * sb[rd, b, i] + fac[rd, 1, b, i] * dz[i]
    # plate acceleration and velocity (trapezoidal; the acceleration first: it needs the old velocity)
    for i in range(n):
        sup[rd, 3, i] = c4 * dz[i] - 2.0 * c2 * sup[rd, 2, i] - sup[rd, 3, i]
    for i in range(n):
        sup[rd, 2, i] = c2 * dz[i] - sup[rd, 2, i]
    for i in range(n):
        sup[rd, 1, i] += dz[i]
    for i in range(n):
        sup[rd, 0, i] += du[i]


@numba.njit(cache=True)
def _solve4(J, r, out):
    """Gaussian elimination with partial pivoting for a 4x4 system (J and r are overwritten)."""
    n = 4
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(J[i, k]) > abs(J[p, k]):
                p = i
        if p != k:
            for j in range(n):
                J[k, j], J[p, j] = J[p, j], J[k, j]
            r[k], r[p] = r[p], r[k]
        for i in range(k + 1, n):
            f = J[i, k] / J[k, k]
            for j in range(k, n):
                J[i, j] -= f * J[k, j]
            r[i] -= f * r[k]
    for i in range(n - 1, -1, -1):
        s = r[i]
        for j in range(i + 1, n):
            s -= J[i, j] * out[j]
        out[i] = s / J[i, i]


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def passage_kernel(i0, i1, dt, Xw, rough, theta, a_y, bogie_idx,
                   xc, xs, vc, vs, Pc, Ps, Pcc, Pcs, coef, W, k1, Gr_self, Gr_pair, wheel_rail,
                   ns, continuous, Cf_point, Lfac, sup, pb, sb, par, fac, table, slot_sleeper, kb_unit, tau, Eb,
                   g0, bitrev, wr, wi,
                   sr, si, bur, bui, lamr, lami, Er, Ei, b0r, b0i, b1r, b1i, br, bi, cr, ci, Gv, snr, sni, C_H,
                   F_hist, acc, Fout, rail_out, wheel_out, newton_fail):
    """Advance the passage from step ``i0`` to ``i1`` (exclusive), updating every state array in place."""
    N1 = xc.shape[1]
    nc = sr.size
    nsens = snr.shape[0]
    n_sleepers = table.shape[2]
    nslot = sup.shape[2]
    xtc = np.empty_like(xc)
    xts = np.empty_like(xc)
    vtc = np.empty_like(xc)
    vts = np.empty_like(xc)
    Psc = np.zeros_like(xc)
    Pss = np.zeros_like(xc)
    cs = np.empty((4, N1))
    sn = np.empty((4, N1))
    bre = np.empty((2, max(ns, 1)))
    bim = np.empty((2, max(ns, 1)))
    are = np.empty(max(ns, 1))
    aim = np.empty(max(ns, 1))
    Ubuf = np.empty(nslot)
    fbuf = np.empty(nslot)
    fbuf2 = np.empty(nslot)
    dub = np.empty(nslot)
    dzb = np.empty(nslot)
    last_q0 = -(2**62)
    # harmonic n folds onto support-DFT bin n mod ns; bin m's mirror is (ns - m) mod ns
    alias = np.zeros(N1, dtype=np.int64)
    mirror = np.zeros(max(ns, 1), dtype=np.int64)
    if not continuous:
        for n in range(N1):
            alias[n] = n % ns
        for m in range(ns):
            mirror[m] = (ns - m) % ns
    # the two wheels on each rail (every rail carries one wheel of each wheelset)
    rail_wheels = np.zeros((2, 2), dtype=np.int64)
    for rail in range(2):
        j = 0
        for w in range(4):
            if wheel_rail[w] == rail and j < 2:
                rail_wheels[rail, j] = w
                j += 1
    sfr = np.empty(nc)
    sfi = np.empty(nc)
    ubr = np.empty(nc)
    ubi = np.empty(nc)
    cfr = np.empty(nc)
    cfi = np.empty(nc)
    ucr = np.zeros((4, 2))  # rail displacement at each wheel without this step's contact force: (z, y)
    vfree = np.zeros(8)
    Fp = np.zeros(4)
    F = np.zeros(4)
    delta0 = np.zeros(4)
    H = np.zeros((4, 4))
    J = np.zeros((4, 4))
    r = np.zeros(4)
    dF = np.zeros(4)
    ny = np.zeros(4)
    nz = np.zeros(4)
    Gn = np.zeros((4, 4))
    for it in range(i0, i1):
        # --- discrete supports: the slot half a ring behind the bogie takes the next sleeper ahead
        if not continuous and bogie_idx[it] != last_q0:
            q0 = bogie_idx[it]
            last_q0 = q0
            for i in range(ns):
                sl = i + ns * ((q0 - i + ns // 2) // ns)
                if sl != slot_sleeper[i]:
                    slot_sleeper[i] = sl
                    sc = min(max(sl, 0), n_sleepers - 1)
                    for rd in range(4):
                        assign_slot(rd, i, sc, table, par, fac, kb_unit, tau, dt, g0, Cf_point[rd % 2])
        # --- contact geometry: normals, rail mode shapes under the wheels, predicted forces
        for w in range(4):
            ny[w] = -np.sin(theta[w, it])
            nz[w] = np.cos(theta[w, it])
            Fp[w] = F_hist[0, w]  # Newton's starting point
        # cos/sin(n k1 X) by the angle-addition recurrence; the four wheels' chains interleaved (they are
        # latency-bound one by one)
        a0 = np.cos(k1 * Xw[0, it])
        b0 = np.sin(k1 * Xw[0, it])
        a1 = np.cos(k1 * Xw[1, it])
        b1 = np.sin(k1 * Xw[1, it])
        a2 = np.cos(k1 * Xw[2, it])
        b2 = np.sin(k1 * Xw[2, it])
        a3 = np.cos(k1 * Xw[3, it])
        b3 = np.sin(k1 * Xw[3, it])
        c0, s0, c1_, s1_, c2, s2, c3, s3 = 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0
        for n in range(N1):
            cs[0, n] = c0
            sn[0, n] = s0
            cs[1, n] = c1_
            sn[1, n] = s1_
            cs[2, n] = c2
            sn[2, n] = s2
            cs[3, n] = c3
            sn[3, n] = s3
            c0, s0 = c0 * a0 - s0 * b0, s0 * a0 + c0 * b0
            c1_, s1_ = c1_ * a1 - s1_ * b1, s1_ * a1 + c1_ * b1
            c2, s2 = c2 * a2 - s2 * b2, s2 * a2 + c2 * b2
            c3, s3 = c3 * a3 - s3 * b3, s3 * a3 + c3 * b3
        # --- rails: free propagation
        for rd in range(4):
            d = rd % 2
            # (one array written per loop: vectorised)
            for n in range(N1):
                xtc[rd, n] = coef[d, 0, n] * xc[rd, n] + coef[d, 1, n] * vc[rd, n] + coef[d, 4, n] * Pc[rd, n]
            for n in range(N1):
                vtc[rd, n] = coef[d, 2, n] * xc[rd, n] + coef[d, 3, n] * vc[rd, n] + coef[d, 6, n] * Pc[rd, n]
            for n in range(N1):
                xts[rd, n] = coef[d, 0, n] * xs[rd, n] + coef[d, 1, n] * vs[rd, n] + coef[d, 4, n] * Ps[rd, n]
            for n in range(N1):
                vts[rd, n] = coef[d, 2, n] * xs[rd, n] + coef[d, 3, n] * vs[rd, n] + coef[d, 6, n] * Ps[rd, n]
        # --- supports of each rail, both directions: predicted contact load, solve, within-step response
        # (the contact forces of the last step act within this one too: their projection from the last step;
        # the wheels have moved by a few mm, the supports only need the within-step effect)
        for rail in range(2):
            if continuous:
                # one foundation oscillator per mode: slot n (cosine), N1 + n (sine)
                for d in range(2):
                    rd = 2 * rail + d
                    for n in range(N1):
                        Ubuf[n] = W[d, n] * (xtc[rd, n] + coef[d, 5, n] * Pcc[rd, n])
                        Ubuf[N1 + n] = W[d, n] * (xts[rd, n] + coef[d, 5, n] * Pcs[rd, n])
                    supports_step(rd, 2 * N1, Ubuf, fbuf, dt, sup, pb, sb, par, Eb, fac, dub, dzb)
                    for n in range(N1):
                        Psc[rd, n] = fbuf[n] * W[d, n] * Lfac[n]
                        Pss[rd, n] = fbuf[N1 + n] * W[d, n] * Lfac[n] if n > 0 else 0.0
                        xtc[rd, n] += coef[d, 5, n] * Psc[rd, n]
                        vtc[rd, n] += coef[d, 7, n] * Psc[rd, n]
                        xts[rd, n] += coef[d, 5, n] * Pss[rd, n]
                        vts[rd, n] += coef[d, 7, n] * Pss[rd, n]
                continue
            # fold the harmonics onto the ns support positions: A_m = sum W_n (x_c - i x_s), m = n mod ns
            for d in range(2):
                rd = 2 * rail + d
                for i in range(ns):
                    bre[d, i] = 0.0
                    bim[d, i] = 0.0
                for n in range(N1):
                    m = alias[n]
                    bre[d, m] += W[d, n] * (xtc[rd, n] + coef[d, 5, n] * Pcc[rd, n])
                    bim[d, m] -= W[d, n] * (xts[rd, n] + coef[d, 5, n] * Pcs[rd, n])
            # Hermitian parts (real synthesis): z goes to the real, y to the imaginary part of one FFT, written
            # in bit-reversed order (the butterflies need no permutation pass)
            for m in range(ns):
                mm = mirror[m]
                q = bitrev[m]
                are[q] = 0.5 * (bre[0, m] + bre[0, mm]) - 0.5 * (bim[1, m] - bim[1, mm])
                aim[q] = 0.5 * (bim[0, m] - bim[0, mm]) + 0.5 * (bre[1, m] + bre[1, mm])
            fft_butterflies(are, aim, True, wr, wi)
            supports_step(2 * rail, ns, are, fbuf, dt, sup, pb, sb, par, Eb, fac, dub, dzb)
            supports_step(2 * rail + 1, ns, aim, fbuf2, dt, sup, pb, sb, par, Eb, fac, dub, dzb)
            for i in range(ns):
                q = bitrev[i]
                are[q] = fbuf[i]
                aim[q] = fbuf2[i]
            fft_butterflies(are, aim, False, wr, wi)
            rz = 2 * rail
            ry = rz + 1
            for n in range(N1):
                m = alias[n]
                mm = mirror[m]
                # split FFT(f_z + i f_y) into FFT(f_z) and FFT(f_y); the rail modes take the support forces
                zr = 0.5 * (are[m] + are[mm])
                zi = 0.5 * (aim[m] - aim[mm])
                yr = 0.5 * (aim[m] + aim[mm])
                yi = -0.5 * (are[m] - are[mm])
                pzc = W[0, n] * zr
                pzs = -W[0, n] * zi
                pyc = W[1, n] * yr
                pys = -W[1, n] * yi
                Psc[rz, n] = pzc
                Pss[rz, n] = pzs
                Psc[ry, n] = pyc
                Pss[ry, n] = pys
                xtc[rz, n] += coef[0, 5, n] * pzc
                vtc[rz, n] += coef[0, 7, n] * pzc
                xts[rz, n] += coef[0, 5, n] * pzs
                vts[rz, n] += coef[0, 7, n] * pzs
                xtc[ry, n] += coef[1, 5, n] * pyc
                vtc[ry, n] += coef[1, 7, n] * pyc
                xts[ry, n] += coef[1, 5, n] * pys
                vts[ry, n] += coef[1, 7, n] * pys
        # rail displacement at the wheels (supports included, this step's contact forces excluded)
        for w in range(4):
            for d in range(2):
                rd = 2 * wheel_rail[w] + d
                acc_u = 0.0
                for n in range(N1):
                    acc_u += W[d, n] * (cs[w, n] * xtc[rd, n] + sn[w, n] * xts[rd, n])
                ucr[w, d] = acc_u
        # --- vehicle: free propagation, slow inputs taken at the end of the step
        ay = a_y[it]
        for m in range(nc):
            ubr[m] = br[8, m] * ay + br[9, m]
            ubi[m] = bi[8, m] * ay + bi[9, m]
        # (one array written per loop throughout: such loops are vectorised)
        for m in range(nc):
            sfr[m] = (Er[m] * sr[m] - Ei[m] * si[m] + b0r[m] * bur[m] - b0i[m] * bui[m]
                      + b1r[m] * ubr[m] - b1i[m] * ubi[m])
        for m in range(nc):
            sfi[m] = (Er[m] * si[m] + Ei[m] * sr[m] + b0r[m] * bui[m] + b0i[m] * bur[m]
                      + b1r[m] * ubi[m] + b1i[m] * ubr[m])
        for k in range(8):
            acc_v = 0.0
            for m in range(nc):
                acc_v += cr[k, m] * sfr[m] - ci[k, m] * sfi[m]
            vfree[k] = acc_v
        # --- contact: Newton on the four normal forces, F = C_H max(δ, 0)^1.5
        for w in range(4):
            delta0[w] = rough[w, it] + ny[w] * (ucr[w, 1] - vfree[2 * w]) + nz[w] * (ucr[w, 0] - vfree[2 * w + 1])
            for w2 in range(4):
                h = (ny[w] * Gv[2 * w, 2 * w2] * ny[w2] + ny[w] * Gv[2 * w, 2 * w2 + 1] * nz[w2]
                     + nz[w] * Gv[2 * w + 1, 2 * w2] * ny[w2] + nz[w] * Gv[2 * w + 1, 2 * w2 + 1] * nz[w2])
                g = 0.0
                if wheel_rail[w] == wheel_rail[w2]:
                    if w == w2:
                        g = nz[w] * Gr_self[0] * nz[w2] + ny[w] * Gr_self[1] * ny[w2]
                    else:
                        g = nz[w] * Gr_pair[0] * nz[w2] + ny[w] * Gr_pair[1] * ny[w2]
                Gn[w, w2] = g
                H[w, w2] = h + g
            F[w] = Fp[w]
        converged = False
        for itn in range(60):
            resmax = 0.0
            for w in range(4):
                dl = delta0[w]
                for w2 in range(4):
                    dl -= H[w, w2] * F[w2]
                if dl > 0.0:
                    sq = np.sqrt(dl)
                    fh = C_H * dl * sq
                    dfh = 1.5 * C_H * sq
                else:
                    fh = 0.0
                    dfh = 0.0
                r[w] = fh - F[w]
                resmax = max(resmax, abs(r[w]))
                for w2 in range(4):
                    J[w, w2] = dfh * H[w, w2]
                J[w, w] += 1.0
            if resmax < 1e-3:  # N
                converged = True
                break
            _solve4(J, r, dF)
            for w in range(4):
                F[w] = max(F[w] + dF[w], 0.0)
        if not converged:
            newton_fail[0] += 1
        # --- rails receive the contact forces
        for rd in range(4):
            d = rd % 2
            wa = rail_wheels[rd // 2, 0]
            wb = rail_wheels[rd // 2, 1]
            ca = -F[wa] * (nz[wa] if d == 0 else ny[wa])
            cb = -F[wb] * (nz[wb] if d == 0 else ny[wb])
            # (one array written per loop: vectorised)
            for n in range(N1):
                Pcc[rd, n] = W[d, n] * ca * cs[wa, n] + W[d, n] * cb * cs[wb, n]
            for n in range(N1):
                Pcs[rd, n] = W[d, n] * ca * sn[wa, n] + W[d, n] * cb * sn[wb, n]
            for n in range(N1):
                xc[rd, n] = xtc[rd, n] + coef[d, 5, n] * Pcc[rd, n]
            for n in range(N1):
                vc[rd, n] = vtc[rd, n] + coef[d, 7, n] * Pcc[rd, n]
            for n in range(N1):
                xs[rd, n] = xts[rd, n] + coef[d, 5, n] * Pcs[rd, n]
            for n in range(N1):
                vs[rd, n] = vts[rd, n] + coef[d, 7, n] * Pcs[rd, n]
            for n in range(N1):
                Pc[rd, n] = Psc[rd, n] + Pcc[rd, n]
            for n in range(N1):
                Ps[rd, n] = Pss[rd, n] + Pcs[rd, n]
        # --- vehicle receives them; sensor accelerations from ds/dt = λ s + b u
        fy0 = F[0] * ny[0]
        fz0 = F[0] * nz[0]
        fy1 = F[1] * ny[1]
        fz1 = F[1] * nz[1]
        fy2 = F[2] * ny[2]
        fz2 = F[2] * nz[2]
        fy3 = F[3] * ny[3]
        fz3 = F[3] * nz[3]
        # modal input of the contact forces (a loop that only writes two arrays: vectorised)
        for m in range(nc):
            cfr[m] = (br[0, m] * fy0 + br[1, m] * fz0 + br[2, m] * fy1 + br[3, m] * fz1
                      + br[4, m] * fy2 + br[5, m] * fz2 + br[6, m] * fy3 + br[7, m] * fz3)
            cfi[m] = (bi[0, m] * fy0 + bi[1, m] * fz0 + bi[2, m] * fy1 + bi[3, m] * fz1
                      + bi[4, m] * fy2 + bi[5, m] * fz2 + bi[6, m] * fy3 + bi[7, m] * fz3)
        for m in range(nc):
            sr[m] = sfr[m] + b1r[m] * cfr[m] - b1i[m] * cfi[m]
        for m in range(nc):
            si[m] = sfi[m] + b1r[m] * cfi[m] + b1i[m] * cfr[m]
        for m in range(nc):
            bur[m] = ubr[m] + cfr[m]
        for m in range(nc):
            bui[m] = ubi[m] + cfi[m]
        # reuse sfr/sfi for ds/dt
        for m in range(nc):
            sfr[m] = lamr[m] * sr[m] - lami[m] * si[m] + bur[m]
        for m in range(nc):
            sfi[m] = lamr[m] * si[m] + lami[m] * sr[m] + bui[m]
        for k in range(nsens):
            a = 0.0
            for m in range(nc):
                a += snr[k, m] * sfr[m] - sni[k, m] * sfi[m]
            acc[k, it] = a
        # --- outputs
        for w in range(4):
            Fout[w, it] = F[w]
            F_hist[1, w] = F_hist[0, w]
            F_hist[0, w] = F[w]
            ru = ny[w] * ucr[w, 1] + nz[w] * ucr[w, 0]
            wu = ny[w] * vfree[2 * w] + nz[w] * vfree[2 * w + 1]
            for w2 in range(4):
                ru -= Gn[w, w2] * F[w2]
                wu += (H[w, w2] - Gn[w, w2]) * F[w2]
            rail_out[w, it] = ru
            wheel_out[w, it] = wu
