"""Writers of small FE export files the way design-office tools write them, for tests/test_fe_exports_real.py.

Independent of :mod:`fem_import` (which reads them) and small on purpose: a
few nodes, elements and modes, written with the layouts of the formats
(UFF 164/2411/2412/55 card images, Nastran punch SORT1 cards, a Nastran
print file's eigenvalue and eigenvector tables, Nastran bulk data in small,
large and free field).
"""

from __future__ import annotations

import numpy as np

#: UFF 2412 descriptors with the beam record (Record 2: orientation node, fore and aft cross sections).
BEAMS = {11, 21, 22, 23, 24}


# ---------------------------------------------------------------------------------------------------------- UFF
def e13(v: float) -> str:
    return f"{v:13.5E}"


def dataset(number: int, lines) -> str:
    return f"{-1:6d}\n{number:6d}\n" + "".join(f"{ln}\n" for ln in lines) + f"{-1:6d}\n"


def uff164(code: int = 1, desc: str = "SI - mks (Newton)", length: float = 1.0, force: float = 1.0) -> str:
    return dataset(164, [f"{code:10d}{desc:<20}{2:10d}",
                         f"{length:25.16E}{force:25.16E}{1.0:25.16E}".replace("E", "D"),
                         f"{273.15:25.16E}".replace("E", "D")])


def uff2411(ids, xyz) -> str:
    lines = []
    for n, (x, y, z) in zip(ids, xyz):
        lines += [f"{int(n):10d}{0:10d}{0:10d}{11:10d}", f"{x:25.16E}{y:25.16E}{z:25.16E}".replace("E", "D")]
    return dataset(2411, lines)


def uff2412(elements) -> str:
    """Elements as (label, descriptor, nodes, property): 6I10, the beam record, node labels 8I10 per line."""
    lines = []
    for eid, desc, nodes, prop in elements:
        lines.append(f"{eid:10d}{desc:10d}{prop:10d}{1:10d}{7:10d}{len(nodes):10d}")
        if desc in BEAMS:
            lines.append(f"{0:10d}{prop:10d}{prop:10d}")
        for k in range(0, len(nodes), 8):
            lines.append("".join(f"{g:10d}" for g in nodes[k:k + 8]))
    return dataset(2412, lines)


def uff55(number: int, freq: float, ids, vals, modal_mass: float = 1.0, fmt=e13) -> str:
    """One normal mode (analysis type 2, real, 3 or 6 values per node, E13.5)."""
    vals = np.asarray(vals, float)
    ndof = vals.shape[1]
    lines = ["railmodal test model", "NONE", "NONE", "NONE", "NONE",
             f"{1:10d}{2:10d}{3 if ndof == 6 else 2:10d}{8:10d}{2:10d}{ndof:10d}",
             f"{2:10d}{4:10d}{1:10d}{number:10d}",
             e13(freq) + e13(modal_mass) + e13(0.0) + e13(0.0)]
    for n, row in zip(ids, vals):
        lines += [f"{int(n):10d}", "".join(fmt(v) for v in row)]
    return dataset(55, lines)


def uff_model(ids, xyz, elements, freqs, shapes, *, numbers=None, units=True) -> str:
    """164 (SI, unless ``units`` is False), 2411, 2412 (if elements), one 55 per mode."""
    numbers = range(1, len(freqs) + 1) if numbers is None else numbers
    text = (uff164() if units else "") + uff2411(ids, xyz) + (uff2412(elements) if elements else "")
    for n, f, s in zip(numbers, freqs, shapes):
        text += uff55(n, f, ids, s)
    return text


# ----------------------------------------------------------------------------------------------- Nastran punch
def punch(modes, *, subcase: int = 1, title: str = "RAILMODAL TEST") -> str:
    """SORT1 eigenvector punch cards: ``modes`` is [(mode number, eigenvalue (rad/s)^2, ids, (n, 6) values)]."""
    out = []
    count = 0

    def card(text):
        nonlocal count
        count += 1
        out.append(f"{text:<72}{count:8d}\n")

    for number, lam, ids, vals in modes:
        for head in (f"$TITLE   = {title}", "$SUBTITLE=", "$LABEL   =", "$EIGENVECTOR", "$REAL OUTPUT",
                     f"$SUBCASE ID = {subcase:11d}", f"$EIGENVALUE = {lam:14.7E}  MODE = {number:5d}"):
            card(head)
        for n, row in zip(ids, np.asarray(vals, float)):
            card(f"{int(n):10d}{'':7}G{row[0]:18.6E}{row[1]:18.6E}{row[2]:18.6E}")
            card(f"-CONT-{'':12}{row[3]:18.6E}{row[4]:18.6E}{row[5]:18.6E}")
    return "".join(out)


# --------------------------------------------------------------------------------------------- Nastran print file
def f06(modes, *, subcase: int = 1, gen_mass=None, rows_per_page: int = 50, title: str = "RAILMODAL TEST",
        scalars=(), echo=()) -> str:
    """An MSC Nastran ``.f06`` of a SOL 103 run: an echo page, the eigenvalue table, and one eigenvector table
    per mode broken over pages of ``rows_per_page`` grid rows (each page with its header and the mode's banner
    again). ``modes`` is [(mode number, eigenvalue (rad/s)^2, ids, (n, 6) values)]; ``gen_mass`` the generalized
    masses printed (1 each by default); ``scalars`` scalar-point ids printed after the grids (one row, zeros);
    ``echo`` small-field card images printed, sorted, as the sorted bulk data echo (pages of ``rows_per_page``)."""
    page = [0]
    out = []

    def header():
        page[0] += 1
        out.append(f"1    {title:<60}DECEMBER   3, 2026  MSC Nastran  2/22/22   PAGE {page[0]:5d}\n")
        out.append(" \n")
        out.append(f"0{'':104}SUBCASE {subcase}\n")

    out.append(f"1    {title:<60}DECEMBER   3, 2026  MSC Nastran  2/22/22   PAGE {page[0]:5d}\n")
    out.append("0        N A S T R A N    E X E C U T I V E    C O N T R O L    E C H O\n")
    out.append("     SOL 103\n     CEND\n")
    cards = sorted(echo, key=lambda c: c[:8])
    for start in range(0, len(cards), rows_per_page):
        header()
        out.append(f"0{'':49}S O R T E D   B U L K   D A T A   E C H O\n")
        out.append(f"{'':17}ENTRY\n{'':17}COUNT        .   1  ..   2  ..   3  ..   4  ..   5  ..   6  ..   7  ..   8  "
                   "..   9  ..  10  .\n")
        for k, card in enumerate(cards[start:start + rows_per_page], start + 1):
            out.append(f"{k:21d}-{'':8}{card}\n")
    if cards:
        out.append(f"{'':30}ENDDATA\n")
    header()
    out.append(f"{'':46}R E A L   E I G E N V A L U E S\n")
    out.append("   MODE    EXTRACTION      EIGENVALUE            RADIANS             CYCLES            GENERALIZED"
               "         GENERALIZED\n")
    out.append("    NO.       ORDER                                                                       MASS      "
               "        STIFFNESS\n")
    gms = np.ones(len(modes)) if gen_mass is None else np.asarray(gen_mass, float)
    for (number, lam, _, _), gm in zip(modes, gms):
        w = np.sqrt(max(lam, 0.0))
        out.append(f"{number:9d}{number:10d}{lam:20.6E}{w:20.6E}{w / (2 * np.pi):20.6E}{gm:20.6E}{gm * lam:20.6E}\n")
    for number, lam, ids, vals in modes:
        vals = np.asarray(vals, float)
        for start in range(0, len(ids), rows_per_page):
            header()
            out.append(f"      EIGENVALUE = {lam:13.6E}\n")
            out.append(f"          CYCLES = {np.sqrt(max(lam, 0.0)) / (2 * np.pi):13.6E}         R E A L   E I G E N V "
                       f"E C T O R   N O . {number:10d}\n")
            out.append(" \n")
            out.append("      POINT ID.   TYPE          T1             T2             T3             R1             R2"
                       "             R3\n")
            for n, row in zip(ids[start:start + rows_per_page], vals[start:start + rows_per_page]):
                cells = "".join("      0.0      " if v == 0 else f"{v:15.6E}" for v in row)
                out.append(f"{int(n):14d}      G  {cells}\n")
        if scalars:
            out.append(f"{int(scalars[0]):14d}      S  " + "      0.0      " * min(6, len(scalars)) + "\n")
    out.append("1                                        * * * END OF JOB * * *\n")
    return "".join(out)


# ------------------------------------------------------------------------------------------------ Nastran bulk
def small(name: str, *fields) -> list[str]:
    """A small-field entry: 8-column fields, 8 per line, continued on lines with a blank name field."""
    texts = [_f8(v) for v in fields]
    lines = []
    for k in range(0, max(len(texts), 1), 8):
        head = f"{name:<8}" if k == 0 else " " * 8
        lines.append(head + "".join(f"{t:<8}" for t in texts[k:k + 8]))
    return lines


def small_plus(name: str, *fields) -> list[str]:
    """A small-field entry continued with explicit '+' markers in field 10 and field 1."""
    texts = [_f8(v) for v in fields]
    lines = []
    for k in range(0, max(len(texts), 1), 8):
        head = f"{name:<8}" if k == 0 else f"+C{k // 8:<6d}"
        cont = f"+C{k // 8 + 1:<6d}" if k + 8 < len(texts) else ""
        lines.append(head + "".join(f"{t:<8}" for t in texts[k:k + 8]).ljust(64) + cont)
    return lines


def large(name: str, *fields) -> list[str]:
    """A large-field entry: 16-column fields, 4 per line, continued on '*' lines."""
    texts = [_f16(v) for v in fields]
    lines = []
    for k in range(0, max(len(texts), 1), 4):
        head = f"{name + '*':<8}" if k == 0 else f"*{'':7}"
        lines.append(head + "".join(f"{t:<16}" for t in texts[k:k + 4]))
    return lines


def free(name: str, *fields) -> list[str]:
    """A free-field entry: commas, 8 data fields per line, continued on '+' lines."""
    texts = ["" if v is None else (repr(v) if isinstance(v, float) else str(v)) for v in fields]
    lines = []
    for k in range(0, max(len(texts), 1), 8):
        head = name if k == 0 else "+"
        lines.append(",".join([head] + texts[k:k + 8]))
    return lines


def _f8(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, str):
        return v
    for p in range(6, 0, -1):
        s = f"{v:.{p}f}"
        if len(s) <= 8:
            return s
    return f"{v:.1E}".replace("E", "")


def _f16(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, str):
        return v
    return f"{v:.9E}"


def grids(ids, xyz, style: str = "free") -> list[str]:
    out = []
    for n, (x, y, z) in zip(ids, xyz):
        if style == "large":
            out += large("GRID", int(n), None, float(x), float(y), float(z))
        elif style == "small":
            out += small("GRID", int(n), None, float(x), float(y), float(z))
        else:
            out += free("GRID", int(n), None, float(x), float(y), float(z))
    return out


def deck(entries, *, header=("SOL 103", "CEND", "TITLE = RAILMODAL TEST", "BEGIN BULK")) -> str:
    return "\n".join(list(header) + list(entries) + ["ENDDATA"]) + "\n"


def element_cards(elements, style_of=lambda k: ("small", "large", "free")[k % 3]) -> list[str]:
    """Nastran cards of UFF elements (21 -> CBAR, 94 -> CQUAD4, 161 -> CONM2, 122 -> RBE2), in rotating styles."""
    write = {"small": small, "large": large, "free": free, "plus": small_plus}
    out = []
    for k, (eid, desc, nodes, prop) in enumerate(elements):
        w = write[style_of(k)]
        if desc == 21:
            out += w("CBAR", eid, prop, nodes[0], nodes[1], 0.0, 0.0, 1.0)
        elif desc == 94:
            out += w("CQUAD4", eid, prop, *nodes)
        elif desc == 161:
            out += w("CONM2", eid, nodes[0], 0, 12.5)
        elif desc == 122:
            out += w("RBE2", eid, nodes[0], 123456, *nodes[1:])
        else:
            raise ValueError(f"no Nastran card for descriptor {desc}")
    return out


# ------------------------------------------------------------------------------------ a free-free lumped model
def lumped_free_free(rigid_hz, flexible_hz, *, seed: int = 0, xyz=None, masses=None):
    """Mass-normalised 3-DOF modes of point masses: six rigid-body modes and flexible ones.

    The rigid-body modes are the rigid motions of the nodes, mass-orthonormalised
    (``Phi^T M Phi = I``); the flexible ones are random, M-orthonormal to them and
    to each other (a stand-in for a structure's flexible modes). Returns
    ``ids, xyz, masses, freqs, shapes (m, n, 3)``; the oracle of the total mass is
    ``masses.sum()``.
    """
    rng = np.random.default_rng(seed)
    if xyz is None:
        xyz = np.array([[0, -0.75, 0], [0, 0.75, 0], [0.46, -0.75, 0], [0, -0.75, 0.46], [0.46, 0.75, 0],
                        [0, 0.75, -0.46], [0.1, 0.0, 0.1], [-0.2, 0.3, 0.05]], float)
    n = len(xyz)
    masses = rng.uniform(20, 200, n) if masses is None else np.asarray(masses, float)
    M = np.repeat(masses, 3)
    r = xyz - xyz.mean(axis=0)
    R = np.zeros((3 * n, 6))
    for i, (x, y, z) in enumerate(r):
        R[3 * i:3 * i + 3, :3] = np.eye(3)
        R[3 * i:3 * i + 3, 3:] = [[0, z, -y], [-z, 0, x], [y, -x, 0]]
    basis = [R[:, k] for k in range(6)] + [rng.standard_normal(3 * n) for _ in flexible_hz]
    modes = []
    for v in basis:
        for u in modes:
            v = v - (u @ (M * v)) * u
        modes.append(v / np.sqrt(v @ (M * v)))
    freqs = np.concatenate([rigid_hz, flexible_hz])
    shapes = np.array(modes).reshape(len(modes), n, 3)
    return np.arange(1, n + 1) * 10, xyz, masses, freqs, shapes
