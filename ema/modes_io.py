"""Saving and loading identified modes (a :class:`~ema.modeset.ModeSet`) as a folder.

Layout of a modes folder (written by ``railmodal lab identify``):

``modes.csv``
    One row per mode: ``mode, f_hz, zeta, mpc, mpd, setup``.
``dofs.csv``
    One row per measured DOF: the channel metadata (``label, node, name, x, y,
    z, dx, dy, dz`` and ``fe_node``, ``setup`` when known).
``shapes.parquet``
    The complex shapes, long format ``mode, dof, re, im``; a DOF a mode was
    not measured at (merged setups) is absent — exact round trip.
``modes.uff``
    The same modes for other tools: UFF 2411 (test nodes at the sensor
    positions) and one UFF 55 per mode (analysis type 3, complex eigenvalue;
    3-DOF global vectors per node, the measured components placed along
    their measuring directions; unmeasured components 0).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pyuff

from .modeset import ModeSet

__all__ = ["write_modeset", "read_modeset", "ModesFolderError"]

log = logging.getLogger("ema")


class ModesFolderError(ValueError):
    """A modes folder that is incomplete or inconsistent."""


def write_modeset(modes: ModeSet, folder: str | Path) -> Path:
    """Write ``modes`` into ``folder`` (created if needed); returns the folder."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    table = modes.to_frame()
    table.insert(0, "mode", np.arange(1, len(modes) + 1))
    table.to_csv(out / "modes.csv", index=False, float_format="%.10g")
    dofs = modes.channels.copy()
    dofs.insert(0, "label", list(modes.dofs))
    dofs.to_csv(out / "dofs.csv", index=False)
    m_idx, d_idx = np.nonzero(np.isfinite(modes.shapes.T))
    long = pd.DataFrame(
        {"mode": m_idx + 1, "dof": d_idx, "re": modes.shapes.T[m_idx, d_idx].real, "im": modes.shapes.T[m_idx, d_idx].imag}
    )
    long.to_parquet(out / "shapes.parquet", index=False)
    _write_uff(modes, out / "modes.uff")
    return out


def _write_uff(modes: ModeSet, path: Path) -> None:
    ch = modes.channels
    nodes = np.unique(ch["node"].astype(int))
    pos = {int(n): ch.loc[ch["node"].astype(int) == n, ["x", "y", "z"]].to_numpy(float)[0] for n in nodes}
    if path.exists():
        path.unlink()
    uff = pyuff.UFF(str(path))
    # pyuff's prepare_* helpers fail on numpy 2 arrays; its writers take plain dicts
    sets = [
        {
            "type": 2411,
            "node_nums": nodes.astype(int),
            "def_cs": np.zeros(len(nodes), int),
            "disp_cs": np.zeros(len(nodes), int),
            "color": np.ones(len(nodes), int),
            "x": np.array([pos[n][0] for n in nodes]),
            "y": np.array([pos[n][1] for n in nodes]),
            "z": np.array([pos[n][2] for n in nodes]),
        }
    ]
    dirs = ch[["dx", "dy", "dz"]].to_numpy(float)
    node_row = {int(n): k for k, n in enumerate(nodes)}
    for j in range(len(modes)):
        vec = np.zeros((len(nodes), 3), complex)
        phi = np.nan_to_num(modes.shapes[:, j])
        for r in range(len(ch)):
            vec[node_row[int(ch["node"].iloc[r])]] += phi[r] * dirs[r]
        s = modes.poles[j]
        sets.append(
            {
                "type": 55,
                "id1": f"railmodal identified mode {j + 1}",
                "id2": f"f = {modes.freqs_hz[j]:.6f} Hz, zeta = {modes.zeta[j]:.6e}, setup {modes.setup[j]}"[:80],
                "id3": "NONE",
                "id4": "NONE",
                "id5": "NONE",
                "model_type": 1,
                "analysis_type": 3,
                "data_ch": 2,
                "spec_data_type": 12,
                "load_case": 1,
                "mode_n": j + 1,
                "eig": complex(s),
                "modal_a": 0j,
                "modal_b": 0j,
                "node_nums": nodes.astype(int),
                "r1": vec[:, 0],
                "r2": vec[:, 1],
                "r3": vec[:, 2],
            }
        )
    uff.write_sets(sets, mode="add")


def read_modeset(folder: str | Path) -> ModeSet:
    """Read a modes folder written by :func:`write_modeset`.

    Raises
    ------
    ModesFolderError
        If a file is missing or the files disagree (naming the file).
    """
    folder = Path(folder)
    for name in ("modes.csv", "dofs.csv", "shapes.parquet"):
        if not (folder / name).exists():
            raise ModesFolderError(f"{folder}: {name} is missing; is this a folder written by 'railmodal lab identify'?")
    table = pd.read_csv(folder / "modes.csv")
    dofs = pd.read_csv(folder / "dofs.csv")
    long = pd.read_parquet(folder / "shapes.parquet")
    for col in ("mode", "f_hz", "zeta", "mpc", "mpd", "setup"):
        if col not in table:
            raise ModesFolderError(f"{folder / 'modes.csv'}: column {col!r} is missing")
    if "label" not in dofs:
        raise ModesFolderError(f"{folder / 'dofs.csv'}: column 'label' is missing")
    m = len(table)
    shapes = np.full((len(dofs), m), np.nan + 0j)
    if len(long):
        if long["mode"].max() > m or long["dof"].max() >= len(dofs) or long["mode"].min() < 1:
            raise ModesFolderError(f"{folder / 'shapes.parquet'} refers to modes/DOFs not in modes.csv/dofs.csv")
        shapes[long["dof"].to_numpy(), long["mode"].to_numpy() - 1] = long["re"].to_numpy() + 1j * long["im"].to_numpy()
    labels = tuple(dofs.pop("label").astype(str))
    return ModeSet(
        freqs_hz=table["f_hz"].to_numpy(float),
        zeta=table["zeta"].to_numpy(float),
        shapes=shapes,
        dofs=labels,
        channels=dofs,
        mpc=table["mpc"].to_numpy(float),
        mpd=table["mpd"].to_numpy(float),
        setup=tuple(table["setup"].astype(str)),
        source=str(folder),
    )
