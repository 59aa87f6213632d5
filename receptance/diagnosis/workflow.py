"""The lab workflow as one library function: from the lab's files to the diagnosed model and its report.

identify (per setup) → merge setups → pair with the FE modes → hybrid model
→ compare → diagnose → add the accepted effects one by one → compare again;
writes ``diagnosis.json``, ``report.html`` (self-contained, figures
embedded), the figures as PNG in ``figures/``, and the diagnosed model
``hybrid_model.npz`` (:mod:`receptance.model_io`) whose modifications say
what belongs to the wheelset in service (:meth:`receptance.ModalModel.for_service`).

:func:`run_lab_diagnosis` is the workflow; it returns a
:class:`LabDiagnosis` and reports progress through a callable (nothing is
printed).  ``railmodal lab diagnose`` only parses its arguments, calls it
and prints.

Setups.  Each setup is a channel table with either the hammer test's time
histories (UFF58 function type 1: hits are screened, H1 estimated with its
coherence) or the FRFs a commercial system exported (UFF58 function type 4,
accelerance/mobility/receptance, ASCII or binary, optionally with
coherence, type 6: :func:`ema.read_frf_uff`).  The noise floor of an FRF
file: with coherence, the H1 formula with the number of averages given
(``n_averages``) or estimated from the coherence and the modal fit; without
coherence, the residual of the identification's modal fit
(:mod:`receptance.diagnosis.noise`); the report says which.

``diagnosis.json``
    The base is :meth:`receptance.diagnosis.Diagnosis.to_json`: ``accepted``
    (``name, params, error_before, error_after, role, assumptions`` in the
    order added, plus ``physical, uncertainty_rel, n_fitted, delta_bic``),
    ``candidates`` (the last round, ranked by ΔBIC), ``rounds`` (every round,
    ranked), ``not_applicable`` (``name, reason, what_would_make_it_apply``),
    ``residual``, ``criterion``, ``initial``, ``noise_floor_method``,
    ``candidate_seconds``, ``workers``; added here: ``final``, ``steps`` (E
    and noise floor of the model before any effect and after each accepted
    effect, per band), ``setups`` (files, hits kept and rejected with
    reasons, modes identified, how the noise floor was obtained),
    ``pairing``, ``model`` (the saved file, its modifications with their
    role and whether the in-service model keeps them), ``description``,
    ``band_hz``, ``inputs``, ``files`` and ``timings_s``. Non-finite numbers
    are written as ``null``.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from receptance.wheelset_description import WheelsetDescription, read_description

__all__ = ["LabDiagnosis", "SetupFiles", "run_lab_diagnosis", "to_jsonable", "MAX_SETUPS"]

log = logging.getLogger("receptance")

#: most setups one diagnosis reads (a wheelset campaign has a handful)
MAX_SETUPS = 20


@dataclass(frozen=True)
class SetupFiles:
    """One setup's files: its channel table and either the hammer-test time histories or the exported FRFs.

    ``hammer`` may be several files (a lab that stores one hit per file): they are read as the hits of one test
    (:func:`ema.read_hammer`)."""

    channels: Path
    hammer: Path | tuple[Path, ...] | None = None
    frf: Path | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "channels", Path(self.channels))
        h = self.hammer
        if isinstance(h, (list, tuple)):
            h = tuple(Path(v) for v in h)
            if not h:
                h = None
            elif len(h) == 1:
                h = h[0]
        object.__setattr__(self, "hammer", None if h is None else (h if isinstance(h, tuple) else Path(h)))
        object.__setattr__(self, "frf", None if self.frf is None else Path(self.frf))
        if (self.hammer is None) == (self.frf is None):
            raise ValueError(f"setup with channel table {self.channels}: give either a hammer-test file or an FRF "
                             f"file, not {'both' if self.hammer else 'neither'}")

    @property
    def files(self) -> tuple[Path, ...]:
        """The data files (one, or the hammer test's several)."""
        d = self.hammer if self.hammer is not None else self.frf
        return d if isinstance(d, tuple) else (d,)

    @property
    def data(self) -> Path:
        """The (first) data file: the setup's default name comes from its stem."""
        return self.files[0]

    @property
    def label(self) -> str:
        """The data files for messages."""
        f = self.files
        return str(f[0]) if len(f) == 1 else f"{f[0]} … {f[-1].name} ({len(f)} files)"

    @property
    def kind(self) -> str:
        return "hammer-test file" if self.hammer is not None else "FRF file"


@dataclass(frozen=True)
class LabDiagnosis:
    """What :func:`run_lab_diagnosis` found and wrote.

    Attributes
    ----------
    out : Path
        The output folder.
    paths : dict of str -> Path
        Files written: ``json``, ``report``, ``model``, ``pairing``,
        ``channel_errors``, ``modes_<setup>`` (folders) and ``figure:<key>``
        for every PNG.
    diagnosis : receptance.diagnosis.Diagnosis
    comparisons : tuple of receptance.diagnosis.Comparison
        The model before any effect, then after each accepted effect.
    pairing : ema.pairing.Pairing
    setups : tuple of dict
        Per setup: files, channels, hits kept and rejected (with reasons),
        exponential window, modes identified, noise floor method.
    timings_s : dict of str -> float
        Seconds per stage (``identify``, ``pair_and_model``, ``compare``,
        ``diagnose``, ``compare_after_effects``, ``figures``, ``total``).
    model : receptance.ModalModel
        The diagnosed model (every accepted effect; :meth:`for_service` for
        the wheelset in service).
    """

    out: Path
    paths: dict
    diagnosis: object = field(repr=False)
    comparisons: tuple = field(repr=False)
    pairing: object = field(repr=False)
    setups: tuple = field(repr=False)
    timings_s: dict = field(default_factory=dict)
    model: object = field(default=None, repr=False)

    @property
    def report(self) -> Path:
        return self.paths["report"]

    @property
    def json(self) -> Path:
        return self.paths["json"]

    def moved(self, out: Path) -> "LabDiagnosis":
        """The same result with its files under ``out`` (after the folder they were written to was renamed)."""
        out = Path(out)
        paths = {k: out / Path(p).relative_to(self.out) for k, p in self.paths.items()}
        return replace(self, out=out, paths=paths)


def to_jsonable(obj):
    """A structure :func:`json.dumps` accepts: numpy scalars and arrays, tuples, paths and DataFrames converted,
    non-finite floats as ``None``."""
    import pandas as pd

    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
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


def _as_setups(setups) -> list[SetupFiles]:
    out = []
    for k, s in enumerate(setups, 1):
        if isinstance(s, SetupFiles):
            out.append(s)
        elif isinstance(s, (tuple, list)) and len(s) == 2:
            out.append(SetupFiles(channels=Path(s[1]), hammer=Path(s[0])))
        else:
            raise ValueError(f"setup {k}: expected SetupFiles(channels, hammer= or frf=) or (hammer file, channel "
                             f"table), got {s!r}")
    return out


def _check_inputs(setups: Sequence[SetupFiles], fem: Path, points: Path) -> None:
    """Fail fast, before minutes of work, on a file that is not there (named with its role)."""
    if not setups:
        raise ValueError("at least one setup (hammer-test or FRF file, and channel table) is needed")
    if len(setups) > MAX_SETUPS:
        raise ValueError(f"at most {MAX_SETUPS} setups, got {len(setups)}")
    for k, s in enumerate(setups, 1):
        for role, p in [(s.kind, f) for f in s.files] + [("channel table", s.channels)]:
            if not p.is_file():
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


def _read_setup(s: SetupFiles, table, name: str, band, max_order: int, n_averages, frf_window_decay, say,
                frame=None):
    """Read, (screen, estimate,) identify one setup; returns the measurement, its modes, synthesis and info.

    ``table`` is in the files' frame; what is read is turned into the railway ``frame``
    (:mod:`receptance.frame`) before it meets the model."""
    from dataclasses import replace

    import ema
    from ema.driving_point import driving_point_checks, driving_point_findings
    from receptance.diagnosis.misfit import Measurement, check_band_lines
    from receptance.diagnosis.noise import estimate_averages, frf_noise_variance

    info = {"setup": name, "channels": str(s.channels)}
    if s.hammer is not None:
        say(f"reading {s.label}")
        test = ema.read_hammer(list(s.files), table)  # the table read and checked before any work, not read again
        if frame is not None and not frame.is_identity:
            test = replace(test, channels=frame.table(test.channels))
        screening = ema.screen_hits(test, band_hz=band)
        frf = ema.estimate_frf(test, band_hz=band, screening=screening)
        force = test.force_channel
        navg = frf.n_averages
        info.update({"hammer": ", ".join(map(str, s.files)), "n_channels": int(frf.n_out), "n_channels_in_file": int(test.n_channels),
                     "force": f"{force['name']} (node {int(force['node'])})", "hits": [int(h) for h in test.hits],
                     "rejected_hits": [int(h) for h in screening.rejected_hits],
                     "rejections": [str(r) for r in screening.rejections],
                     "n_averages": [int(np.min(navg)), int(np.max(navg))] if navg is not None else None})
        say(f"{name}: {test.n_hits} hits x {test.n_channels} channels, {len(screening.rejections)} rejection(s); "
            f"identifying (LSCE to order {max_order}, LSFD)")
    else:
        say(f"reading FRFs {s.frf}")
        # the decay: --window-decay, else the file's note, else none (the reader warns that damping is as exported)
        frf = ema.read_frf_uff(s.frf, table, exp_window_decay=frf_window_decay)
        if frame is not None and not frame.is_identity:
            frf = replace(frf, channels=frame.table(frf.channels))
        if frf.quantity != "accelerance":
            frf = frf.as_quantity("accelerance")
        try:
            frf = frf.select(band_hz=band)
        except ValueError as exc:
            raise ValueError(f"{s.frf}: {exc}") from None
        info.update({"frf": str(s.frf), "n_channels": int(frf.n_out), "n_channels_in_file": int(frf.n_out),
                     "force": str(frf.inputs[0]), "hits": [], "rejected_hits": [], "rejections": [],
                     "n_averages": None, "coherence_in_file": frf.coherence is not None})
        say(f"{name}: {frf.n_out} FRFs read ({'with' if frf.coherence is not None else 'without'} coherence); "
            f"identifying (LSCE to order {max_order}, LSFD)")
    # the diagnosis' octave cells must be resolved by this setup's lines: refused before minutes of identification
    check_band_lines(band, frf.freqs_hz, f"setup {name!r} ({s.label})")
    result = ema.identify(frf, band_hz=band, max_order=max_order, setup=name)
    noise_var, method = None, ""
    if s.frf is not None:
        if frf.coherence is not None:
            if n_averages is not None:
                frf = frf.with_history(f"{n_averages} averages (given)", n_averages=np.full(frf.n_out, int(n_averages)))
                method = (f"H1 random error from the file's coherence and {int(n_averages)} averages (given)")
            else:
                n = estimate_averages(frf, result.synthesis)
                frf = frf.with_history("number of averages estimated", n_averages=n)
                method = (f"H1 random error from the file's coherence; the number of averages is not in the file and "
                          f"was estimated from the coherence and the modal-fit residual ({int(np.min(n))}-"
                          f"{int(np.max(n))}); give it (--averages) if known")
            info["n_averages"] = [int(np.min(frf.n_averages)), int(np.max(frf.n_averages))]
        else:
            noise_var, method = frf_noise_variance(frf, result.synthesis)
    elif frf.n_averages is None or int(np.min(frf.n_averages)) < 2:
        # one hit left (one recorded, or the others rejected): H1 has no coherence to give a noise floor
        noise_var, method = frf_noise_variance(frf, result.synthesis)
        log.warning("setup %r (%s): a single hit is averaged for some channels, so the FRFs have no coherence; the "
                    "noise floor comes from the modal fit's residual (an upper bound). Record several hits per setup.",
                    name, s.label)
        method = f"single hit, no coherence: {method}"
    info.update({"n_lines": int(frf.freqs_hz.size), "band_hz": f"{band[0]:g}–{band[1]:g}",
                 "exp_window_decay": float(frf.exp_window_decay), "n_modes": len(result.modes),
                 "modes": [{"f_hz": float(f), "zeta": float(z), "mpc": float(m)}
                           for f, z, m in zip(result.modes.freqs_hz, result.modes.zeta, result.modes.mpc)]})
    framed = table if frame is None else frame.table(table)
    checks = driving_point_checks(result.modes, framed)
    for finding in driving_point_findings(checks, source=f"setup {name!r} ({s.label})"):
        log.warning("%s", finding)
    info["driving_points"] = [{"channel": c.channel, "verdict": c.verdict,
                               "wrong_share": c.wrong_share if np.isfinite(c.wrong_share) else None} for c in checks]
    meas = Measurement(frf, framed, name, noise_variance=noise_var, noise_method=method)
    info["noise_floor_method"] = meas.noise_method
    say(f"{name}: {len(result.modes)} modes identified")
    return meas, result, frf, info


def run_lab_diagnosis(setups, fem: Path, points: Path, out: Path, *, band_hz: tuple[float, float] = (10.0, 500.0),
                      max_effects: int = 3, max_order: int = 100, mac_min: float = 0.8,
                      description: WheelsetDescription | Path | str | None = None, n_averages: int | None = None,
                      frf_window_decay: float | None = None, workers: int | None = None,
                      geometry: Path | None = None, total_mass: float | None = None,
                      progress: Callable[[str], None] | None = None, fe_units: str | None = None,
                      mode_margin: float = 1.0) -> LabDiagnosis:
    """Run the lab workflow on one or more setups and write the diagnosis, the diagnosed model and the report.

    Parameters
    ----------
    setups : sequence of SetupFiles or of (hammer file, channel table)
        Per setup: the channel table (CSV with the force row) and the
        hammer-test time histories or the exported FRFs. Setup names come
        from the table's ``setup`` column, else the file name; they must
        differ.
    fem : Path
        FE modes export (UFF 2411/2412/55 or Nastran punch), the richer the
        better (modes above ``band_hz`` are the basis of the structural
        modifications; the model reports only modes up to ``band_hz[1]``).
    points : Path
        Points table (``name, fe_node, x, y, z``: contact_L, axlebox_L, ...).
    out : Path
        Output folder (created; files are written into it as they are made —
        the command line stages it and renames on success).
    band_hz : (float, float)
        Identification, comparison and diagnosis band [Hz]: its octave cells
        define ``E``, the noise floor and every fit and score of the
        diagnosis (:func:`receptance.diagnosis.misfit.octave_edges`). It must
        lie within the measured lines with at least
        :data:`~receptance.diagnosis.misfit.MIN_CELL_LINES` lines per octave
        (``low`` ≥ about that many line spacings), and the FE export must
        reach into its top octave (better: a few times the band). A wheelset on soft slings has its rig modes at
        a few hertz: a band from about 4 Hz lets the diagnosis see them.
    max_effects : int
        Most effects accepted one after the other.
    mode_margin : float
        The model's receptances keep the modes up to ``mode_margin × band_hz[1]``
        (:attr:`ModalModel.max_hz`), in [1, 4].  A mode just above the band is in
        a real wheelset's measurement (near resonance at the band's top); a mode
        at ``r`` times the top left out answers the top with ``1/(r² − 1)`` times
        its static flexibility beyond what a constant residual stands for (25 at
        r = 1.02, 0.8 at r = 1.5), so 1.5 suits a real wheelset.  Default 1 (the
        band's top): the virtual lab's truth holds no mode above ``fe_max_hz``
        (the band's top for the default design), and a wider model would add the
        FE's modes at 540 Hz the data lacks.
    max_order : int
        Largest LSCE model order of the identification.
    mac_min : float
        Smallest MAC of a test–FE pair.
    description : WheelsetDescription or path to its TOML file, optional
        What the FE cannot tell (:mod:`receptance.wheelset_description`;
        Table 2.1 defaults otherwise).
    n_averages : int, optional
        Averages behind the coherence of FRF files (estimated when not given).
    frf_window_decay : float, optional
        Exponential-window decay [1/s] of FRF files (default: recorded in the
        file's header by ``ema.write_frf_uff``, else 0).
    workers : int, optional
        Parallel processes for the candidates' fits (default: usable cores).
    geometry : Path, optional
        Node coordinates for an FE file without them (a Nastran punch): UFF
        2411 or Nastran GRID cards (default: a companion file of the same
        name; :func:`fem_import.read_with_geometry`).
    fe_units : str, optional
        The unit system of an FE export that does not state it (a key of
        :data:`fem_import.modes.UNIT_SYSTEMS`, e.g. ``"mm-t-s"``); None: SI.
    total_mass : float, optional
        The wheelset's true mass [kg] as exported (with whatever axleboxes
        the FE holds): the rigid-body modes must give it within 5 %
        (:func:`receptance.hybrid.check_fe_for_model`); without it they must
        give a railway wheelset's mass.
    progress : callable, optional
        Receives one line per stage (and per fitted candidate).

    Returns
    -------
    LabDiagnosis

    Raises
    ------
    FileNotFoundError
        An input file is missing (the message names it and its role).
    fem_import.MassNormalisationError, fem_import.MissingCoordinatesError, receptance.dofs.DofError
        The FE export is not mass-normalised, has no node coordinates, or a
        point or sensor is not on (near) its FE node: found before any
        identification.
    receptance.diagnosis.DiagnosisError
        The FE export's highest mode lies below the band's top octave cell
        (before any identification) or outside a setup's measured lines, or an octave
        cell holds too few lines (before that setup's identification).
    ValueError
        Duplicate setup names, bad band or counts, an unreadable description;
        the readers' and the model's own errors (``ema.HammerDataError``,
        ``fem_import.FEImportError``, ``receptance.ModelError``,
        ``receptance.diagnosis.DiagnosisError``) pass through, naming file,
        channel or mode.
    """

    import fem_import
    from ema.channels import read_channels
    from ema.merge import merge_setups
    from ema.pairing import pair_modes
    from ema.polarity import channel_polarity, polarity_findings
    from receptance.diagnosis.compare import compare
    from receptance.diagnosis.diagnose import diagnose
    from receptance.diagnosis.errors import DiagnosisError
    from receptance.diagnosis.misfit import octave_edges
    from fem_import.modes import shapes_at_channels
    from receptance.dofs import check_points, read_points
    from receptance.diagnosis.scale import check_modal_scale, modal_scale
    from receptance.frame import to_railway_frame
    from receptance.hybrid import check_fe_for_model, hybrid_model

    say = progress or (lambda msg: None)
    setups = _as_setups(setups)
    fem, points, out = Path(fem), Path(points), Path(out)
    band = (float(band_hz[0]), float(band_hz[1]))
    if not (0 < band[0] < band[1]):
        raise ValueError(f"band_hz must be (low, high) with 0 < low < high, got {band_hz!r}")
    if not isinstance(max_effects, int) or not 0 <= max_effects <= 10:
        raise ValueError(f"max_effects must be an integer 0-10, got {max_effects!r}")
    if not (isinstance(mode_margin, (int, float)) and math.isfinite(mode_margin) and 1 <= mode_margin <= 4):
        raise ValueError(f"mode_margin must be a number in [1, 4] (times the band's top), got {mode_margin!r}")
    if n_averages is not None and not (isinstance(n_averages, int) and 2 <= n_averages <= 10000):
        raise ValueError(f"n_averages must be an integer 2-10000, got {n_averages!r}")
    if frf_window_decay is not None and not (math.isfinite(frf_window_decay) and 0 <= frf_window_decay <= 1000):
        raise ValueError(f"frf_window_decay must be a decay in 0-1000 1/s, got {frf_window_decay!r}")
    if total_mass is not None and not (math.isfinite(total_mass) and 0 < total_mass <= 1e6):
        raise ValueError(f"total_mass must be a mass in (0, 1e6] kg, got {total_mass!r}")
    if geometry is not None and not Path(geometry).is_file():
        raise FileNotFoundError(f"geometry file (node coordinates of {fem}) not found: {geometry}")
    _check_inputs(setups, fem, points)
    if description is not None and not isinstance(description, WheelsetDescription):
        description = read_description(description)
    desc = description or WheelsetDescription()
    timings: dict[str, float] = {}
    t_all = time.perf_counter()

    # ---- validate the tables and the names before any long work
    names, tables = [], []
    for s in setups:
        table = read_channels(s.channels)
        name = _setup_name(table, s.data)
        if name in names:
            raise ValueError(f"setups {setups[names.index(name)].label} and {s.label} have the same name {name!r} "
                             f"(the channel tables' 'setup' column, else the file name); give each setup its own, or, "
                             f"if they are the hits of one setup stored in several files, give them all after one "
                             f"--hammer (SetupFiles(hammer=[...]))")
        names.append(name)
        tables.append(table)
    point_table = read_points(points)
    say(f"reading {fem}")
    fe, where = fem_import.read_with_geometry(fem, geometry, units=fe_units)
    say(where)
    rb = check_fe_for_model(fe, total_mass=total_mass)
    if rb is not None:
        say(f"rigid-body modes: total mass {rb.mass:.1f} kg (mass-normalised shapes)")
    top_cell = octave_edges(band)[-2:]
    if float(np.max(fe.freqs_hz)) < top_cell[0]:
        # an export that stops below the band's top octave cannot describe that cell at all (a mere gap in the
        # spectrum above the last mode is possible, so the export stopping between the cell's edges is only
        # warned about, by hybrid_model, as is one below twice the band)
        raise DiagnosisError(f"{fem}: the FE export's highest mode is at {float(np.max(fe.freqs_hz)):.1f} Hz, below "
                             f"the band's top octave {top_cell[0]:g}–{top_cell[1]:g} Hz: the model would have no "
                             f"mode there; lower the band's upper edge (--band) or export the FE modes to a few "
                             f"times the band")
    check_points(fe, point_table, source=str(points))
    for table in tables:
        shapes_at_channels(fe, table)  # every sensor on (near) its fe_node, named in the error
    # the files are read in their own frame (a hammer file's direction codes are checked against its table there);
    # the FE, the points, the tables and the description are then turned into the railway frame the points define
    frame, point_table, fe, _, desc = to_railway_frame(point_table, fe, description=desc, source=str(points))
    if not frame.is_identity:
        say(frame.describe())

    # ---- identify each setup
    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    figdir = out / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    measurements, results, frfs, info = [], [], [], []
    for s, table, name in zip(setups, tables, names):
        meas, result, frf, inf = _read_setup(s, table, name, band, max_order, n_averages, frf_window_decay, say,
                                             frame)
        # units and normalisation on both sides, before minutes of fitting (receptance.diagnosis.scale)
        scale = modal_scale(result.modes, fe, frame.table(table), setup=name)
        if scale is not None:
            inf["modal_scale"] = {"ratio": scale.ratio, "n_modes": scale.n_modes}
            say(f"{name}: measured modal constants {scale.ratio:.3g} × the FE's ({scale.n_modes} well-paired modes)")
        check_modal_scale(scale, fem=str(fem), measurement=s.label)
        measurements.append(meas)
        results.append(result)
        frfs.append(frf)
        info.append(inf)
    timings["identify"] = time.perf_counter() - t0

    # ---- pair and build the hybrid model
    t0 = time.perf_counter()
    sets = [r.modes for r in results]
    test_modes = merge_setups(sets) if len(sets) > 1 else sets[0]
    say(f"{len(test_modes)} test modes from {len(sets)} setup(s); pairing with {len(fe)} FE modes")
    pairing = pair_modes(test_modes, fe, threshold=mac_min)
    polarity = channel_polarity(test_modes, fe, pairing)
    for finding in polarity_findings(polarity):
        log.warning("%s", finding)
    model = hybrid_model(fe, pairing, points=point_table, keep_fe="all", max_hz=mode_margin * band[1])
    n_paired = len(pairing.pairs)
    model_note = (f"Hybrid model (thesis §2.3): the FE shapes of {fe.source or fem.name} "
                  f"({len(fe)} modes up to {fe.freqs_hz.max():.0f} Hz) with the test's frequency and damping for the "
                  f"{n_paired} paired modes; every other FE mode is kept with its FE frequency as the basis of the "
                  f"structural modifications, and the model holds modes up to {mode_margin * band[1]:g} Hz "
                  f"({mode_margin:g} × the test band's top)."
                  + ("" if frame.is_identity else f" Frame: {frame.describe()}."))
    say(f"{n_paired} pairs (MAC >= {mac_min:g}); hybrid model of {len(fe)} FE modes, modes up to "
        f"{mode_margin * band[1]:g} Hz")
    timings["pair_and_model"] = time.perf_counter() - t0

    # ---- compare and diagnose
    t0 = time.perf_counter()
    c0 = compare(model, measurements, band_hz=band)
    say(c0.describe().splitlines()[0])
    timings["compare"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    say(f"diagnosing (up to {max_effects} effects; every candidate fitted to {len(measurements)} setup(s))")
    diagnosis = diagnose(model, measurements, max_effects=max_effects, progress=say, description=desc,
                         workers=workers, band_hz=band)
    timings["diagnose"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    comparisons = [c0] + [compare(f.model, measurements, band_hz=band) for f in diagnosis.accepted]
    timings["compare_after_effects"] = time.perf_counter() - t0

    # ---- files
    paths = _write_results(out, setups, names, results, frfs, pairing, test_modes, fe, diagnosis, comparisons, info,
                           model_note, band, desc, fem, points, timings, t_all, say, frame, polarity)
    return LabDiagnosis(out, paths, diagnosis, tuple(comparisons), pairing, tuple(info), timings, diagnosis.model)


def _write_results(out, setups, names, results, frfs, pairing, test_modes, fe, diagnosis, comparisons, info,
                   model_note, band, desc, fem, points, timings, t_all, say, frame, polarity) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ema.modes_io import write_modeset
    from ema.plot import plot_stabilisation, plot_synthesis
    from ema.plot_pairing import plot_mac
    from ema.polarity import polarity_findings
    from receptance.diagnosis.plot_compare import plot_band_errors, plot_before_after, plot_error_map, plot_peaks
    from receptance.diagnosis.report import write_diagnosis_report
    from receptance.model_io import save_model
    from receptance.plot_model import plot_comparison

    figdir = out / "figures"
    figures: dict[str, Path] = {}
    paths: dict[str, Path] = {}
    t0 = time.perf_counter()
    say("plotting")
    for name, result, frf in zip(names, results, frfs):
        slug = _slug(name)
        paths[f"modes_{name}"] = write_modeset(result.modes, out / f"modes_{slug}")
        figures[f"stabilisation_{name}"] = _save(plot_stabilisation(result.diagram, frf=frf),
                                                 figdir / f"stabilisation_{slug}.png", plt)
        figures[f"synthesis_{name}"] = _save(plot_synthesis(frf, result.synthesis), figdir / f"synthesis_{slug}.png",
                                             plt)
    pairing.to_csv(out / "pairing.csv")
    paths["pairing"] = out / "pairing.csv"
    polarity.to_csv(out / "channel_polarity.csv", index=False, float_format="%.6g")
    paths["channel_polarity"] = out / "channel_polarity.csv"
    figures["mac"] = _save(plot_mac(pairing, test_modes, fe), figdir / "mac.png", plt)
    c0 = comparisons[0]
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

    # ---- the diagnosed model, tables, json, report
    model = diagnosis.model
    paths["model"] = save_model(model, out / "hybrid_model.npz")
    service = model.for_service()
    kept = {id(m) for m in service.modifications}
    model_doc = {"file": "hybrid_model.npz",
                 "modifications": [{"kind": m.kind, "role": getattr(m, "role", "wheelset"),
                                    "kept_in_service": id(m) in kept} for m in model.modifications],
                 "channel_terms": [t.kind for t in model.channel_terms],
                 "service": "receptance.load_model('hybrid_model.npz').for_service() keeps the wheelset properties "
                            "(bearings, press fits) and drops the test artefacts (rig, sensor masses, curve fits)"}
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
    doc["channel_polarity"] = polarity_findings(polarity)
    doc["model"] = model_doc
    doc["description"] = desc.to_dict()
    doc["frame"] = {"rotation_fe_to_railway": frame.rotation.tolist(), "note": frame.describe(),
                    "basis": frame.basis}
    doc["band_hz"] = list(band)
    doc["inputs"] = {"setups": [{s.kind.split()[0]: [str(f) for f in s.files] if len(s.files) > 1 else str(s.data),
                                 "channels": str(s.channels)} for s in setups],
                     "fem": str(fem), "points": str(points), "description": desc.source or None}
    doc["files"] = {k: os.path.relpath(p, out) for k, p in paths.items()}
    doc["timings_s"] = timings
    text = json.dumps(to_jsonable(doc), indent=1, allow_nan=False)
    paths["json"].write_text(text + "\n", encoding="utf-8")
    inputs = {f"setup {n}": f"{s.label} + {s.channels}" for n, s in zip(names, setups)}
    inputs.update({"FE modes": str(fem), "points": str(points), "band": f"{band[0]:g}–{band[1]:g} Hz",
                   "wheelset description": desc.source or "none (thesis Table 2.1 defaults)"})
    write_diagnosis_report(
        paths["report"], diagnosis=diagnosis, comparisons=comparisons, figures=figures, setups_info=info,
        pairing_table=pairing.table, timings=timings, model_note=model_note, inputs=inputs,
        polarity=polarity_findings(polarity),
        files={k: str(v) for k, v in paths.items() if not k.startswith("figure:")}, model_doc=model_doc)
    say(f"report written: {paths['report']}")
    return paths
