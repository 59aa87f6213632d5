"""Write the CalculiX decks of the .frd files beside this script (run ``python make_bar.py`` and ``ccx bar``,
``ccx bar_two_steps``, CalculiX 2.20; then gzip the .frd files).

A free steel bar, 30 x 20 mm (x, y) and 400 mm long (z), of 20-node bricks (C3D20), in SI units: E = 210 GPa,
nu = 0.3, rho = 7850 kg/m^3, so 1.884 kg. ``bar``: one *FREQUENCY step, 12 modes (6 rigid-body). ``bar_two_steps``:
a coarser bar, a free *FREQUENCY step (8 modes), then a second with the end z = 0 clamped (4 modes).
"""

import itertools

A, B, L = 0.03, 0.02, 0.40
# C3D20 node order: the 8 corners, the mid-sides of the z = 0 face's edges, of the z = 1 face's, then the 4 along z
CORNERS = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2)]
MIDS = [(1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0), (1, 0, 2), (2, 1, 2), (1, 2, 2), (0, 1, 2),
        (0, 0, 1), (2, 0, 1), (2, 2, 1), (0, 2, 1)]


def deck(path, nx, ny, nz, steps):
    ids, xyz = {}, []

    def node(key):
        if key not in ids:
            ids[key] = len(ids) + 1
            xyz.append((key[0] * A / (2 * nx), key[1] * B / (2 * ny), key[2] * L / (2 * nz)))
        return ids[key]

    elements = [[node((2 * i + di, 2 * j + dj, 2 * k + dk)) for di, dj, dk in CORNERS + MIDS]
                for i, j, k in itertools.product(range(nx), range(ny), range(nz))]
    with open(path, "w") as f:
        f.write(f"*HEADING\nfree steel bar 30 x 20 x 400 mm, C3D20 {nx} x {ny} x {nz}, SI units\n*NODE, NSET=NALL\n")
        for n, p in enumerate(xyz, 1):
            f.write(f"{n}, {p[0]:.9g}, {p[1]:.9g}, {p[2]:.9g}\n")
        f.write("*NSET, NSET=END0\n" + "\n".join(str(n) for n, p in enumerate(xyz, 1) if p[2] == 0) + "\n")
        f.write("*ELEMENT, TYPE=C3D20, ELSET=EALL\n")
        for e, nodes in enumerate(elements, 1):
            f.write(f"{e}, " + ", ".join(map(str, nodes[:15])) + ",\n" + ", ".join(map(str, nodes[15:])) + "\n")
        f.write("*MATERIAL, NAME=STEEL\n*ELASTIC\n210e9, 0.3\n*DENSITY\n7850.\n"
                "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n")
        for modes, clamped in steps:
            f.write("*STEP\n*FREQUENCY\n%d\n" % modes + ("*BOUNDARY\nEND0, 1, 3\n" if clamped else "")
                    + "*NODE FILE\nU\n*END STEP\n")


if __name__ == "__main__":
    deck("bar.inp", 2, 2, 12, [(12, False)])
    deck("bar_two_steps.inp", 1, 1, 6, [(8, False), (4, True)])
