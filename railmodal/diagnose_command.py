"""``railmodal lab diagnose``: the whole lab workflow from hammer-test files to the diagnosis report.

identify (per setup) → merge setups → pair with the FE modes → hybrid model
→ compare → diagnose → add the accepted effects one by one → compare again;
writes ``diagnosis.json``, ``report.html`` (self-contained, figures embedded)
and the figures as PNG in ``figures/``.

:func:`run_lab_diagnosis` is the workflow (returns a :class:`LabDiagnosis`;
progress through a callable, logging otherwise, nothing printed);
:func:`add_diagnose_parser` and :func:`cmd_diagnose` are the command line.

``diagnosis.json``
    The base is :meth:`receptance.diagnose.Diagnosis.to_json`: ``accepted``
    (``name, params, error_before, error_after`` in the order added, plus
    ``physical, uncertainty_rel, n_fitted, delta_bic``), ``candidates`` (the
    last round, ranked by ΔBIC), ``rounds`` (every round, ranked),
    ``residual`` (where the remaining error sits), ``criterion``,
    ``initial``; added here: ``final``, ``steps`` (E and noise floor of the
    model before any effect and after each accepted effect, per band),
    ``setups`` (files, hits kept and rejected with reasons, modes
    identified), ``pairing``, ``band_hz``, ``inputs``, ``files`` and
    ``timings_s`` (seconds per stage). Non-finite numbers are written as
    ``null``.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

__all__ = ["LabDiagnosis", "run_lab_diagnosis", "add_diagnose_parser", "cmd_diagnose", "to_jsonable"]

log = logging.getLogger("railmodal")


@dataclass(frozen=True)
class LabDiagnosis:
    """What :func:`run_lab_diagnosis` found and wrote.

    Attributes
    ----------
    out : Path
        The output folder.
    paths : dict of str -> Path
        Files written: ``json``, ``report``, ``pairing``, ``channel_errors``,
        ``modes_<setup>`` (folders) and ``figure:<key>`` for every PNG.
    diagnosis : receptance.diagnose.Diagnosis
    comparisons : tuple of receptance.compare.Comparison
        The model before any effect, then after each accepted effect.
    pairing : ema.pairing.Pairing
    setups : tuple of dict
        Per setup: files, channels, hits kept and rejected (with reasons),
        exponential window, modes identified.
    timings_s : dict of str -> float
        Seconds per stage.
    """

    out: Path
    paths: dict
    diagnosis: object = field(repr=False)
    comparisons: tuple = field(repr=False)
    pairing: object = field(repr=False)
    setups: tuple = field(repr=False)
    timings_s: dict = field(default_factory=dict)

    @property
    def report(self) -> Path:
        return self.paths["report"]

    @property
    def json(self) -> Path:
        return self.paths["json"]


def to_jsonable(obj):
    """A structure :func:`json.dumps` accepts: numpy scalars and arrays, tuples, paths and DataFrames converted,
    non-finite floats as ``None``."""
    import pandas as pd

    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, pd.DataFrame):
        return to_jsonable(obj.to_dict(orient="records"))
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if math.isfinite(x) else None
    if isinstance(obj, (complex, np.complexfloating)):
        return {"re": to_jsonable(obj.real), "im": to_jsonable(obj.imag)}
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, str):
        return obj
    if obj is pd.NA or obj is pd.NaT:
        return None
    return str(obj)


def _check_inputs(setups: Sequence[tuple[Path, Path]], fem: Path, points: Path) -> None:
    """Fail fast, before minutes of work, on a file that is not there (named with its role)."""
    if not setups:
        raise ValueError("at least one setup (hammer-test file and channel table) is needed")
    for k, pair in enumerate(setups, 1):
        if len(pair) != 2:
            raise ValueError(f"setup {k}: expected (hammer file, channel table), got {pair!r}")
        for role, p in zip(("hammer-test file", "channel table"), pair):
            if not Path(p).is_file():
                raise FileNotFoundError(f"setup {k}: {role} not found: {p}")
    if not Path(fem).is_file():
        raise FileNotFoundError(f"FE modes file not found: {fem} (expected a UFF 2411/2412/55 or Nastran .pch "
                                f"export)")
    if not Path(points).is_file():
        raise FileNotFoundError(f"points table not found: {points} (expected name, fe_node, x, y, z for "
                                f"contact_L, axlebox_L, contact_R, axlebox_R)")


def _setup_name(table, path: Path) -> str:
    if "setup" in table and table["setup"].notna().any():
        return str(table["setup"].dropna().iloc[0])
    return path.stem


def _slug(name: str) -> str:
    """A file-name-safe form of a setup name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "setup"


def _save(fig, path: Path, plt) -> Path:
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def run_lab_diagnosis(setups: Sequence[tuple[Path, Path]], fem: Path, points: Path, out: Path, *,
                      band_hz: tuple[float, float] = (10.0, 500.0), max_effects: int = 3, max_order: int = 100,
                      mac_min: float = 0.8, progress: Callable[[str], None] | None = None) -> LabDiagnosis:
    """Run the lab workflow on one or more hammer setups and write the diagnosis and its report.

    Parameters
    ----------
    setups : sequence of (Path, Path)
        Per setup: the UFF58 hammer-test file and its channel table (CSV with
        the force row). Setup names come from the table's ``setup`` column,
        else the file name; they must differ.
    fem : Path
        FE modes export (UFF 2411/2412/55 or Nastran punch), the richer the
        better (modes above ``band_hz`` are the basis of the structural
        modifications; the model reports only modes up to ``band_hz[1]``).
    points : Path
        Points table (``name, fe_node, x, y, z``: contact_L, axlebox_L, ...).
    out : Path
        Output folder (created).
    band_hz : (float, float)
        Identification and comparison band [Hz].
    max_effects : int
        Most effects accepted one after the other.
    max_order : int
        Largest LSCE model order of the identification.
    mac_min : float
        Smallest MAC of a test–FE pair.
    progress : callable, optional
        Receives one line per stage (and per fitted candidate).

    Returns
    -------
    LabDiagnosis

    Raises
    ------
    FileNotFoundError
        An input file is missing (the message names it and its role).
    ValueError
        Duplicate setup names, bad band; the readers' and the model's own
        errors (``ema.HammerDataError``, ``fem_import.FEImportError``,
        ``receptance.ModelError``) pass through, naming file, channel or mode.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    import ema
    import fem_import
    from ema.merge import merge_setups
    from ema.modes_io import write_modeset
    from ema.pairing import pair_modes
    from ema.plot import plot_stabilisation, plot_synthesis
    from ema.plot_pairing import plot_mac
    from receptance.compare import compare
    from receptance.diagnose import Measurement, diagnose
    from receptance.dofs import read_points
    from receptance.hybrid import hybrid_model
    from receptance.plot_compare import plot_band_errors, plot_before_after, plot_error_map, plot_peaks
    from receptance.plot_model import plot_comparison
    from receptance.report import write_diagnosis_report

    say = progress or (lambda msg: None)
    setups = [(Path(h), Path(c)) for h, c in setups]
    fem, points, out = Path(fem), Path(points), Path(out)
    band = (float(band_hz[0]), float(band_hz[1]))
    if not (0 < band[0] < band[1]):
        raise ValueError(f"band_hz must be (low, high) with 0 < low < high, got {band_hz!r}")
    if max_effects < 0:
        raise ValueError(f"max_effects must be >= 0, got {max_effects!r}")
    _check_inputs(setups, fem, points)
    figdir = out / "figures"
    timings: dict[str, float] = {}
    figures: dict[str, Path] = {}
    paths: dict[str, Path] = {}
    t_all = time.perf_counter()

    # ---- identify each setup
    t0 = time.perf_counter()
    names: list[str] = []
    tables = []
    for hammer, channels in setups:
        try:
            table = pd.read_csv(channels)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
            raise ValueError(f"{channels}: cannot read the channel table: {exc}") from exc
        name = _setup_name(table, hammer)
        if name in names:
            raise ValueError(f"setups {setups[names.index(name)][0]} and {hammer} have the same name {name!r} (the "
                             f"channel tables' 'setup' column, else the file name); give each setup its own")
        names.append(name)
        tables.append(table)
    figdir.mkdir(parents=True, exist_ok=True)
    modesets, measurements, info = [], [], []
    for (hammer, channels), table, name in zip(setups, tables, names):
        say(f"reading {hammer}")
        test = ema.read_hammer(hammer, channels)
        screening = ema.screen_hits(test, band_hz=band)
        frf = ema.estimate_frf(test, band_hz=band, screening=screening)
        say(f"{name}: {test.n_hits} hits x {test.n_channels} channels, {len(screening.rejections)} rejection(s); "
            f"identifying (LSCE to order {max_order}, LSFD)")
        result = ema.identify(frf, band_hz=band, max_order=max_order, setup=name)
        modes = result.modes
        modesets.append(modes)
        slug = _slug(name)
        paths[f"modes_{name}"] = write_modeset(modes, out / f"modes_{slug}")
        figures[f"stabilisation_{name}"] = _save(plot_stabilisation(result.diagram, frf=frf), figdir /
                                                 f"stabilisation_{slug}.png", plt)
        figures[f"synthesis_{name}"] = _save(plot_synthesis(frf, result.synthesis), figdir / f"synthesis_{slug}.png",
                                             plt)
        force = test.force_channel
        navg = frf.n_averages
        info.append({
            "setup": name, "hammer": str(hammer), "channels": str(channels), "n_channels": int(frf.n_out),
            "n_channels_in_file": int(test.n_channels),
            "force": f"{force['name']} (node {int(force['node'])})", "hits": [int(h) for h in test.hits],
            "rejected_hits": [int(h) for h in screening.rejected_hits],
            "rejections": [str(r) for r in screening.rejections],
            "n_averages": [int(np.min(navg)), int(np.max(navg))] if navg is not None else None,
            "n_lines": int(frf.freqs_hz.size), "band_hz": f"{band[0]:g}–{band[1]:g}",
            "exp_window_decay": float(frf.exp_window_decay), "n_modes": len(modes),
            "modes": [{"f_hz": float(f), "zeta": float(z), "mpc": float(m)}
                      for f, z, m in zip(modes.freqs_hz, modes.zeta, modes.mpc)]})
        measurements.append(Measurement(frf, table, name))
        say(f"{name}: {len(modes)} modes identified")
    timings["identify"] = time.perf_counter() - t0

    # ---- pair and build the hybrid model
    t0 = time.perf_counter()
    sets = modesets
    test_modes = merge_setups(sets) if len(sets) > 1 else sets[0]
    say(f"{len(test_modes)} test modes from {len(sets)} setup(s); reading {fem}")
    fe = fem_import.read(fem)
    pairing = pair_modes(test_modes, fe, threshold=mac_min)
    pairing.to_csv(out / "pairing.csv")
    paths["pairing"] = out / "pairing.csv"
    figures["mac"] = _save(plot_mac(pairing, test_modes, fe), figdir / "mac.png", plt)
    model = hybrid_model(fe, pairing, points=read_points(points), keep_fe="all", max_hz=band[1])
    n_paired = len(pairing.pairs)
    model_note = (f"Hybrid model (thesis §2.3): the FE shapes of {fe.source or fem.name} "
                  f"({len(fe)} modes up to {fe.freqs_hz.max():.0f} Hz) with the test's frequency and damping for the "
                  f"{n_paired} paired modes; every other FE mode is kept with its FE frequency as the basis of the "
                  f"structural modifications, and the model reports modes up to {band[1]:g} Hz like the test band.")
    say(f"{n_paired} pairs (MAC >= {mac_min:g}); hybrid model of {len(fe)} FE modes, reported up to {band[1]:g} Hz")
    timings["pair_and_model"] = time.perf_counter() - t0

    # ---- compare and diagnose
    t0 = time.perf_counter()
    triples = [(m.setup, m.frf, m.channels) for m in measurements]
    c0 = compare(model, triples, band_hz=band)
    say(c0.describe().splitlines()[0])
    timings["compare"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    say(f"diagnosing (up to {max_effects} effects; every candidate fitted to {len(measurements)} setup(s))")
    diagnosis = diagnose(model, measurements, max_effects=max_effects, progress=say)
    timings["diagnose"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    comparisons = [c0] + [compare(f.model, triples, band_hz=band) for f in diagnosis.accepted]
    timings["compare_after_effects"] = time.perf_counter() - t0

    # ---- figures
    t0 = time.perf_counter()
    say("plotting the comparisons")
    figures["error_map"] = _save(plot_error_map(c0), figdir / "error_map.png", plt)
    figures["band_errors"] = _save(plot_band_errors(c0, by_body=True), figdir / "band_errors.png", plt)
    worst = list(c0.ranking.loc[c0.ranking["kind"] == "channel", "name"].head(4))
    figures["worst_channels"] = _save(plot_comparison(c0, worst), figdir / "worst_channels.png", plt)
    figures["peaks"] = _save(plot_peaks(c0), figdir / "peaks.png", plt)
    for k, fit in enumerate(diagnosis.accepted, 1):
        before, after = comparisons[k - 1], comparisons[k]
        figures[f"before_after_{k}"] = _save(
            plot_before_after(before, after, labels=("before" if k == 1 else f"with effects 1–{k - 1}",
                                                     f"with {fit.name}")),
            figdir / f"before_after_{k}_{fit.name}.png", plt)
    if diagnosis.accepted:
        final = comparisons[-1]
        figures["error_map_final"] = _save(plot_error_map(final), figdir / "error_map_final.png", plt)
        figures["worst_channels_final"] = _save(plot_comparison(final, worst), figdir / "worst_channels_final.png",
                                                plt)
    timings["figures"] = time.perf_counter() - t0

    # ---- tables, json, report
    errors = c0.channels[["key", "setup", "channel", "body"]].copy()
    errors["band_error_model"] = c0.channels["band_error"].to_numpy(float)
    errors["floor"] = c0.channels["floor"].to_numpy(float)
    for k, (fit, c) in enumerate(zip(diagnosis.accepted, comparisons[1:]), 1):
        errors[f"band_error_with_{k}_{fit.name}"] = c.channels["band_error"].to_numpy(float)
    errors.to_csv(out / "channel_errors.csv", index=False, float_format="%.6g")
    paths["channel_errors"] = out / "channel_errors.csv"
    for key, p in figures.items():
        paths[f"figure:{key}"] = p
    paths["json"] = out / "diagnosis.json"
    paths["report"] = out / "report.html"
    timings["total"] = time.perf_counter() - t_all

    doc = diagnosis.to_json()
    by_name = {f.name: f for f in diagnosis.accepted}
    for item in doc["accepted"]:
        f = by_name[item["name"]]
        item.update({"physical": f.physical, "uncertainty_rel": f.uncertainty, "n_fitted": f.n_fitted,
                     "delta_bic": f.delta_bic, "note": f.note})
    labels = ["model"] + [f"+ {f.name}" for f in diagnosis.accepted]
    doc["final"] = {"summary_error": diagnosis.final.summary, "noise_floor": diagnosis.final.noise_floor}
    doc["steps"] = [{"model": lab, "summary_error": c.summary, "noise_floor": c.noise_floor,
                     "bands": [{"band_hz": [r.lo_hz, r.hi_hz], "error": r.error, "floor": r.floor}
                               for r in c.bands.itertuples()]} for lab, c in zip(labels, comparisons)]
    doc["setups"] = info
    doc["pairing"] = pairing.table
    doc["band_hz"] = list(band)
    doc["inputs"] = {"setups": [{"hammer": str(h), "channels": str(c)} for h, c in setups], "fem": str(fem),
                     "points": str(points)}
    doc["files"] = {k: os.path.relpath(p, out) for k, p in paths.items()}
    doc["timings_s"] = timings
    text = json.dumps(to_jsonable(doc), indent=1, allow_nan=False)
    paths["json"].write_text(text + "\n", encoding="utf-8")
    write_diagnosis_report(
        paths["report"], diagnosis=diagnosis, comparisons=comparisons, figures=figures, setups_info=info,
        pairing_table=pairing.table, timings=timings, model_note=model_note,
        inputs={**{f"setup {n}": f"{h} + {c}" for n, (h, c) in zip(names, setups)}, "FE modes": str(fem),
                "points": str(points), "band": f"{band[0]:g}–{band[1]:g} Hz"},
        files={k: str(v) for k, v in paths.items() if not k.startswith("figure:")})
    say(f"report written: {paths['report']}")
    return LabDiagnosis(out, paths, diagnosis, tuple(comparisons), pairing, tuple(info), timings)


# --------------------------------------------------------------------------- command line
def _progress_printer(quiet: bool) -> Callable[[str], None]:
    if quiet:
        return lambda msg: None
    return lambda msg: print(f"  … {msg}", file=sys.stderr, flush=True)


def _undetermined(fit, name: str) -> bool:
    u = (fit.uncertainty or {}).get(name)
    return u is not None and not (math.isfinite(float(u)) and float(u) <= 1.0)


def summarise(result: LabDiagnosis) -> list[str]:
    """A few lines for the terminal: accepted effects, error before/after, what remains, where the report is."""
    d = result.diagnosis
    c = result.comparisons
    lines = [f"model vs measurement: error E {100 * c[0].summary:.2f} % (noise floor {100 * c[0].noise_floor:.2f} %)"]
    if d.accepted:
        for k, f in enumerate(d.accepted, 1):
            params = ", ".join(f"{n} = {v:.4g}" + (" (undetermined)" if _undetermined(f, n) else "")
                               for n, v in f.params.items())
            lines.append(f"  effect {k}: {f.name} ({params}): E {100 * f.error_before:.2f} % -> "
                         f"{100 * f.error_after:.2f} %")
    else:
        lines.append("  no catalogued effect passed the criterion")
    if d.accepted:
        lines.append(f"final error E {100 * c[-1].summary:.2f} % (noise floor {100 * c[-1].noise_floor:.2f} %)")
    for u in d.unexplained:
        lines.append(f"  {u}")
    lines.append(f"report:    {result.report}")
    lines.append(f"diagnosis: {result.json}")
    return lines


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Handler of ``railmodal lab diagnose`` (see :func:`add_diagnose_parser`)."""
    hammers, channels = list(args.hammer or []), list(args.channels or [])
    if len(hammers) != len(channels):
        args._diagnose_parser.error(f"each --hammer needs its --channels (in the same order): got {len(hammers)} "
                                    f"--hammer and {len(channels)} --channels")
    t0 = time.perf_counter()
    result = run_lab_diagnosis(list(zip(hammers, channels)), Path(args.fem), Path(args.points), Path(args.out),
                               band_hz=tuple(args.band), max_effects=args.max_effects, max_order=args.max_order,
                               mac_min=args.mac_min, progress=_progress_printer(args.quiet))
    for line in summarise(result):
        print(line)
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def add_diagnose_parser(lab_subparsers) -> argparse.ArgumentParser:
    """Register ``railmodal lab diagnose`` on the ``lab`` subparsers; returns its parser."""
    d = lab_subparsers.add_parser(
        "diagnose", help="hammer tests + FE export -> identify, pair, hybrid model, compare, diagnose; "
                         "diagnosis.json and report.html",
        description="Identify the modes of every setup, pair them with the FE modes, build the hybrid model, "
                    "compare it with the measured FRFs, find the missing physical effects one by one, and write "
                    "diagnosis.json and a self-contained report.html (figures also as PNG in the figures/ folder of --out).")
    d.add_argument("--hammer", required=True, action="append",
                   help="UFF58 hammer-test file of one setup (repeat for several setups, each with its --channels)")
    d.add_argument("--channels", required=True, action="append",
                   help="channel table CSV of the preceding --hammer file")
    d.add_argument("--fem", required=True, help="FE modes file (UFF 2411/2412/55 or Nastran .pch)")
    d.add_argument("--points", required=True, help="points table CSV: name, fe_node, x, y, z")
    d.add_argument("--out", required=True, help="output folder")
    d.add_argument("--band", nargs=2, type=float, default=[10.0, 500.0], metavar=("LOW", "HIGH"),
                   help="identification and comparison band [Hz] (default 10 500)")
    d.add_argument("--max-effects", type=int, default=3, help="most effects accepted one after the other (default 3)")
    d.add_argument("--max-order", type=int, default=100, help="largest LSCE model order (default 100)")
    d.add_argument("--mac-min", type=float, default=0.8, help="smallest MAC of a test-FE pair (default 0.8)")
    d.set_defaults(func=cmd_diagnose, _diagnose_parser=d)
    return d
