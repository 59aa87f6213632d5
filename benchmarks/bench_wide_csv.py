"""Reading a wide CSV export (``ema.wide_csv``): the one-pass parse beside the cell-by-cell one, time and memory.

Two tables of 300 000 rows (23 s of a hammer test at 12.8 kHz), a time column and 30 channels written to 7
significant digits (about 125 MB): every channel at the rows' rate (a hammer-test export), and the last channel
written every tenth row only (a slower channel, blank cells between). The tables are written and each reading
runs in a process of its own, so that a reading's peak resident memory is its own (Linux keeps a process's peak
across ``exec``: a reader forked from the writer would report the writer's).

    python benchmarks/bench_wide_csv.py
"""

import _checkout  # noqa: F401

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROWS, CHANNELS = 300_000, 30

READ = """
import json, resource, sys, time
from pathlib import Path
sys.path[:0] = {path!r}
from ema import wide_csv
path, how = Path(sys.argv[1]), sys.argv[2]
t0 = time.perf_counter()
if how == "one pass":
    table = wide_csv.read_wide_table(path, ValueError)
    n = sum(c.values.size for c in table.columns.values())
else:
    names = [(f"ch{{j}}", "g") for j in range({channels})]
    cols = ["time [s]"] + [f"ch{{j}} [g]" for j in range({channels})]
    n = sum(c.values.size for c in wide_csv._columns_cell_by_cell(path, 0, ",", False, cols, names, 1.0, ValueError,
                                                                   "table").values())
print(json.dumps({{"s": time.perf_counter() - t0, "samples": n,
                  "gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}}))
"""


def write(path: Path, slow_every: int) -> Path:
    rng = np.random.default_rng(0)
    t = np.arange(ROWS) / 12800.0
    data = rng.standard_normal((ROWS, CHANNELS)).astype(np.float32)
    with open(path, "w") as fh:
        fh.write(",".join(["time [s]"] + [f"ch{j} [g]" for j in range(CHANNELS)]) + "\n")
        rows = np.char.add(np.char.mod("%.7f", t), ",")
        body = np.array([",".join(r) for r in np.char.mod("%.6e", data)])
        lines = np.char.add(rows, body)
        if slow_every > 1:
            keep = np.arange(ROWS) % slow_every == 0
            lines[~keep] = np.array([ln.rsplit(",", 1)[0] + "," for ln in lines[~keep]])
        fh.write("\n".join(lines) + "\n")
    return path


def main() -> None:
    code = READ.format(path=[str(p) for p in sys.path[:2]], channels=CHANNELS)
    with tempfile.TemporaryDirectory() as tmp:
        print(f"{ROWS} rows x {CHANNELS} channels + time, 7 significant digits")
        for label, every in (("every channel at the rows' rate", 1), ("the last channel every 10th row", 10)):
            path = Path(tmp) / f"t{every}.csv"
            subprocess.run([sys.executable, __file__, "--write", str(path), str(every)], check=True)
            print(f"\n{label} ({path.stat().st_size / 1e6:.0f} MB)")
            got = {}
            for how in ("one pass", "cell by cell"):
                out = subprocess.run([sys.executable, "-c", code, str(path), how], capture_output=True, text=True,
                                     check=True)
                got[how] = json.loads(out.stdout)
                print(f"  {how:13s} {got[how]['s']:6.2f} s   peak {got[how]['gb']:5.2f} GB   "
                      f"{got[how]['samples']} samples")
            assert got["one pass"]["samples"] == got["cell by cell"]["samples"]
            print(f"  one pass: {got['cell by cell']['s'] / got['one pass']['s']:.1f}x faster, "
                  f"{got['cell by cell']['gb'] / got['one pass']['gb']:.1f}x less memory")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--write"]:
        write(Path(sys.argv[2]), int(sys.argv[3]))
    else:
        main()
