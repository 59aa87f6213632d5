"""Helpers of the bad-input tests: locate and corrupt records of the virtual lab's files.

Every bad file is made from a good virtual-lab campaign inside the test: these
helpers find a dataset's bytes in a binary UFF58 (by hit and node), and build a
small good campaign (fewer hits, channels and samples) for the property-based
tests, written with the lab's own UFF writer.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ema.hammer_io import _scan_uff
from railmodal.cli import main


@dataclass(frozen=True)
class Dataset58:
    """Where one binary UFF58 dataset sits in the file."""

    index: int  # 1-based
    hit: int
    node: int
    header: int  # offset of the '    58b' line
    header_line6: int  # offset of record 6 (function type, hit, node)
    data: int  # offset of the first data byte
    n_bytes: int


def datasets58(raw: bytes) -> list[Dataset58]:
    """Every binary dataset 58 of ``raw`` with its hit (``ver_num``) and response node."""
    out = []
    for k, (kind, binary, start, end) in enumerate(_scan_uff(raw, "memory"), 1):
        if kind != 58 or not binary:
            continue
        head_end = raw.index(b"\n", start) + 1
        head = raw[start:head_end]
        n_ascii, n_bytes = int(head[19:31]), int(head[31:43])
        lines = []
        pos = head_end
        for _ in range(n_ascii):
            e = raw.index(b"\n", pos) + 1
            lines.append((pos, raw[pos:e]))
            pos = e
        rec6_pos, rec6 = lines[5]
        hit = int(rec6[15:20])
        node = int(rec6[41:51])
        out.append(Dataset58(k, hit, node, start, rec6_pos, pos, n_bytes))
    return out


def find58(raw: bytes, hit: int, node: int) -> Dataset58:
    for d in datasets58(raw):
        if d.hit == hit and d.node == node:
            return d
    raise KeyError(f"no dataset for hit {hit}, node {node}")


def float32_at(raw: bytes | bytearray, d: Dataset58, k: int) -> float:
    return float(np.frombuffer(bytes(raw[d.data + 4 * k:d.data + 4 * k + 4]), "<f4")[0])


def scale_node(raw: bytearray, node: int, factor: float) -> None:
    """Multiply the samples of one channel in every hit by ``factor`` (a wrong sensitivity), in place."""
    for d in datasets58(bytes(raw)):
        if d.node == node:
            x = np.frombuffer(bytes(raw[d.data:d.data + d.n_bytes]), "<f4") * np.float32(factor)
            raw[d.data:d.data + d.n_bytes] = x.astype("<f4").tobytes()


def zero_node(raw: bytearray, node: int, hits=None) -> None:
    """All samples of one channel set to 0 (a dead channel), in place."""
    for d in datasets58(bytes(raw)):
        if d.node == node and (hits is None or d.hit in hits):
            raw[d.data:d.data + d.n_bytes] = bytes(d.n_bytes)


def copy_campaign(src: Path, dst: Path, names=("flexural.uff", "flexural_channels.csv", "fe_design.uff",
                                                "points.csv")) -> Path:
    dst.mkdir(parents=True, exist_ok=True)
    for n in names:
        shutil.copy(src / n, dst / n)
    return dst


def run(argv, capsys) -> tuple[int, str, str]:
    """The CLI in-process: (exit status, stdout, stderr); argparse errors give their status 2."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    text = capsys.readouterr()
    return code, text.out, text.err


def modes_csv(folder: Path) -> np.ndarray:
    return pd.read_csv(folder / "modes.csv")["f_hz"].to_numpy(float)


def same_modes(a, b, rtol: float = 5e-4) -> bool:
    """Same number of modes, every frequency within ``rtol`` (0.05 %)."""
    a, b = np.sort(np.asarray(a, float)), np.sort(np.asarray(b, float))
    return a.size == b.size and bool(np.all(np.abs(a - b) <= rtol * b))


def nothing_written(out: Path) -> bool:
    """``out`` was not created and no partial folder of it was left beside it."""
    return not out.exists() and not any(p.name.startswith(f".{out.name}.partial-") for p in out.parent.iterdir())


# ---------------------------------------------------------------------------- a small good campaign
SMALL_BAND = ("60", "300")
SMALL_ORDER = "30"


def small_campaign(src: Path, dst: Path, *, hits=(1, 2, 4, 6), n_channels: int = 8, seconds: float = 1.0) -> Path:
    """A small good hammer test written from the campaign ``src``: a few clean hits and channels, shorter records.

    Written with the virtual lab's UFF58 writer (binary), with its channel table; the FE export and the
    points table are copied.
    """
    import ema
    from lab_data.uff_export import TimeHistory, write_time_histories

    test = ema.read_hammer(src / "flexural.uff", src / "flexural_channels.csv")
    table = pd.read_csv(src / "flexural_channels.csv")
    acc = table[table["quantity"] == "acceleration"].reset_index(drop=True)
    # spread the kept channels over the setup (axle, discs, wheels)
    keep = np.unique(np.linspace(0, len(acc) - 1, n_channels).round().astype(int))
    n = int(seconds * test.fs)
    force_row = table[table["quantity"] == "force"].iloc[0]
    hist = []
    for h in hits:
        i = test.hits.index(h)
        hist.append(TimeHistory(h, int(force_row["node"]), 0, "force", "N", str(force_row["name"]), test.dt,
                                test.force[i, :n].astype(np.float32), int(force_row["node"]), 0))
        for j in keep:
            r = acc.iloc[j]
            hist.append(TimeHistory(h, int(r["node"]), 0, "acceleration", "m/s^2", str(r["name"]), test.dt,
                                    test.responses[i, j, :n].astype(np.float32), int(force_row["node"]), 0))
    dst.mkdir(parents=True, exist_ok=True)
    write_time_histories(dst / "flexural.uff", hist, binary=True)
    pd.concat([table[table["quantity"] == "force"], acc.iloc[keep]]).to_csv(dst / "flexural_channels.csv",
                                                                          index=False)
    for name in ("fe_design.uff", "points.csv"):
        shutil.copy(src / name, dst / name)
    return dst


def identify_small(folder: Path, out: Path, capsys, hammer: str = "flexural.uff",
                   channels: str = "flexural_channels.csv") -> tuple[int, str, str]:
    return run(["-q", "lab", "identify", "--hammer", str(folder / hammer), "--channels", str(folder / channels),
                "--band", *SMALL_BAND, "--max-order", SMALL_ORDER, "--out", str(out)], capsys)


def identify_and_pair(src: Path, folder: Path) -> tuple[Path, Path]:
    """The small campaign of ``src`` in ``folder``, its clean modes (``folder/modes``) and their pairing with its FE
    export (``folder/pairing``), by the CLI."""
    small_campaign(src, folder)
    modes, pairing = folder / "modes", folder / "pairing"
    assert main(["-q", "lab", "identify", "--hammer", str(folder / "flexural.uff"), "--channels",
                 str(folder / "flexural_channels.csv"), "--band", *SMALL_BAND, "--max-order", SMALL_ORDER,
                 "--out", str(modes)]) == 0
    assert main(["-q", "lab", "pair", "--modes", str(modes), "--fem", str(folder / "fe_design.uff"), "--out",
                 str(pairing)]) == 0
    return modes, pairing


def write_fe(path: Path, fe, *, shapes=None, freqs=None) -> Path:
    """An FE export written by the virtual lab's UFF writer from ``fe`` (optionally other shapes/frequencies)."""
    from lab_data.uff_export import ElementRecord, write_fe_uff

    elements = [ElementRecord(e.element_id, e.fe_descriptor, e.physical_property, 0, 0, tuple(e.nodes))
                for e in fe.elements]
    return write_fe_uff(path, fe.node_ids, fe.xyz, elements, fe.freqs_hz if freqs is None else freqs,
                        fe.shapes if shapes is None else shapes, model_name="bad-input test")


def uff55_blocks(text: str) -> tuple[list[str], list[tuple[int, int]]]:
    """Lines of a universal file and the (first, last) line index of every dataset 55 (between its -1 tags)."""
    lines = text.split("\n")
    blocks = []
    k = 0
    while k < len(lines):
        if lines[k].strip() == "-1" and k + 1 < len(lines) and lines[k + 1].strip() == "55":
            end = next(j for j in range(k + 2, len(lines)) if lines[j].strip() == "-1")
            blocks.append((k, end))
            k = end + 1
        else:
            k += 1
    return lines, blocks


def grid_cards(node_ids, xyz) -> str:
    """A Nastran bulk data deck with the nodes as GRID cards, in the three field formats in turn."""
    out = ["$ grids of the bad-input test", "SOL 103", "CEND", "BEGIN BULK"]
    for k, (n, (x, y, z)) in enumerate(zip(node_ids, xyz)):
        if k % 3 == 0:  # small field, 8 columns
            out.append(f"GRID    {n:<8d}        {x:8.5f}{y:8.5f}{z:8.5f}")
        elif k % 3 == 1:  # large field, 16 columns and a continuation
            out.append(f"GRID*   {n:<16d}{'':16s}{x:16.9E}{y:16.9E}*")
            out.append(f"*       {z:16.9E}")
        else:  # free field
            out.append(f"GRID,{n},,{x:.9g},{y:.9g},{z:.9g}")
    out.append("ENDDATA")
    return "\n".join(out) + "\n"
