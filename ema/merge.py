"""Merging the mode lists of several sensor setups (thesis §3.2: flexural and torsional setups).

Setups share some channels (the axlebox accelerometers stay in place). A
mode seen in two setups is one mode: two modes of different setups are the
same when their frequencies agree (``f_rtol``) and their shapes agree on the
shared channels (MAC >= ``mac_min``) with visible amplitude there. The merged
shape is the union of both setups' DOFs, the second setup's part scaled to
the first on the shared channels (complex least squares). A mode seen in one
setup only has NaN at the DOFs it was not measured at. Frequency and damping
of a merged mode are the means of the setups' estimates.

DOFs are identified by node and measuring direction: the same node measured
in another direction (a sensor turned from radial to tangential) is another
DOF, labelled ``name@setup`` when the names clash.
"""

from __future__ import annotations

import logging
import numpy as np
import pandas as pd

from .modeset import ModeSet

__all__ = ["merge_setups"]

log = logging.getLogger("ema")


def _dof_key(row) -> tuple:
    return (int(row["node"]), round(float(row["dx"]), 3), round(float(row["dy"]), 3), round(float(row["dz"]), 3))


def merge_setups(modesets: list[ModeSet], *, f_rtol: float = 2e-3, mac_min: float = 0.9,
                 visible: float = 0.05) -> ModeSet:
    """Merge per-setup mode sets into one (see module docstring).

    Parameters
    ----------
    modesets : list of ModeSet
        One per setup; their ``channels`` must have ``node, name, dx, dy, dz``.
    f_rtol : float
        Largest relative frequency difference of the same mode in two setups.
    mac_min : float
        Smallest MAC on the shared channels for the same mode.
    visible : float
        A mode is visible on the shared channels when their norm is at least
        this fraction of the mode's largest component (otherwise shared
        channels cannot tell two modes apart and both are kept).

    Returns
    -------
    ModeSet
    """
    if not modesets:
        raise ValueError("merge_setups needs at least one mode set")
    if len(modesets) == 1:
        return modesets[0]
    # union of DOFs
    keys: list[tuple] = []
    rows: list[dict] = []
    labels: list[str] = []
    index_of: dict[tuple, int] = {}
    maps = []
    for k_set, ms in enumerate(modesets):
        local = []
        for r, (_, row) in enumerate(ms.channels.iterrows()):
            key = _dof_key(row)
            if key not in index_of:
                index_of[key] = len(keys)
                keys.append(key)
                d = row.to_dict()
                label = ms.dofs[r]
                if label in labels:
                    setup = row.get("setup") if isinstance(row.get("setup"), str) else f"setup{k_set + 1}"
                    label = f"{label}@{setup}"
                labels.append(label)
                rows.append(d)
            local.append(index_of[key])
        maps.append(np.array(local))
    n_dof = len(keys)

    modes: list[dict] = []  # each: f list, zeta list, shape (n_dof,) complex, setups, mpc list, mpd list
    for ms, idx in zip(modesets, maps):
        for j in range(len(ms)):
            shape = np.full(n_dof, np.nan + 0j)
            shape[idx] = ms.shapes[:, j]
            cand = _match(modes, ms.freqs_hz[j], shape, f_rtol, mac_min, visible)
            if cand is None:
                modes.append({"f": [ms.freqs_hz[j]], "zeta": [ms.zeta[j]], "shape": shape, "setup": [ms.setup[j]],
                              "mpc": [ms.mpc[j]], "mpd": [ms.mpd[j]]})
            else:
                m = modes[cand]
                shared = np.isfinite(m["shape"]) & np.isfinite(shape)
                a, b = m["shape"][shared], shape[shared]
                scale = np.vdot(b, a) / np.vdot(b, b)
                new = np.isnan(m["shape"]) & np.isfinite(shape)
                m["shape"][new] = scale * shape[new]
                for key, v in (("f", ms.freqs_hz[j]), ("zeta", ms.zeta[j]), ("setup", ms.setup[j]),
                               ("mpc", ms.mpc[j]), ("mpd", ms.mpd[j])):
                    m[key].append(v)
                log.info("mode at %.2f Hz seen in setups %s: merged", m["f"][0], "+".join(m["setup"]))
    modes.sort(key=lambda m: np.mean(m["f"]))
    channels = pd.DataFrame(rows).reset_index(drop=True)
    return ModeSet(
        freqs_hz=np.array([np.mean(m["f"]) for m in modes]),
        zeta=np.array([np.mean(m["zeta"]) for m in modes]),
        shapes=np.column_stack([m["shape"] for m in modes]) if modes else np.zeros((n_dof, 0), complex),
        dofs=tuple(labels),
        channels=channels,
        mpc=np.array([np.min(m["mpc"]) for m in modes]),
        mpd=np.array([np.max(m["mpd"]) for m in modes]),
        setup=tuple("+".join(dict.fromkeys(m["setup"])) for m in modes),
        scaling=modesets[0].scaling,
        source=" + ".join(ms.source for ms in modesets),
        history=("merged setups " + ", ".join(dict.fromkeys(s for ms in modesets for s in ms.setup)),),
    )


def _match(modes: list[dict], f: float, shape: np.ndarray, f_rtol: float, mac_min: float, visible: float):
    best, best_mac = None, mac_min
    for k, m in enumerate(modes):
        if abs(np.mean(m["f"]) - f) > f_rtol * f:
            continue
        shared = np.isfinite(m["shape"]) & np.isfinite(shape)
        if not shared.any():
            continue
        a, b = m["shape"][shared], shape[shared]
        vis_a = np.linalg.norm(a) >= visible * np.nanmax(np.abs(m["shape"]))
        vis_b = np.linalg.norm(b) >= visible * np.nanmax(np.abs(shape))
        if not (vis_a and vis_b):
            continue
        mac = abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real)
        if mac >= best_mac:
            best, best_mac = k, mac
    return best
