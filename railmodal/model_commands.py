"""``railmodal model ...``: track receptance and hybrid wheelset model from the command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from railmodal.arguments import (add_geometry_argument, band_action, bounded_float, bounded_int, existing_file, existing_folder,
                                 output_folder)

__all__ = ["add_model_commands"]


def _progress(quiet: bool):
    if quiet:
        return lambda msg: None
    return lambda msg: print(f"  … {msg}", file=sys.stderr, flush=True)


def _agg():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: Frequency axis of ``model track`` [Hz] and the most lines it computes.
TRACK_BAND_HZ = (1.0, 2000.0)
MAX_TRACK_LINES = 200_000


def _track_lines(df: float) -> str | None:
    n = int(np.floor((TRACK_BAND_HZ[1] - TRACK_BAND_HZ[0]) / df)) + 1
    if n > MAX_TRACK_LINES:
        return f"{n} frequency lines over {TRACK_BAND_HZ[0]:g}-{TRACK_BAND_HZ[1]:g} Hz, at most {MAX_TRACK_LINES}"
    return None


def _cmd_track(args: argparse.Namespace) -> int:
    import pandas as pd

    from receptance.plot_track import plot_track_receptance
    from receptance.track import pinned_pinned_frequency, track_receptance
    from receptance.trackform import Trackform, TrackformError, check_trackform, load_trackform

    from railmodal.output import staged_output

    plt = _agg()
    # validate first: the trackform (file or Table 2.2), then compute, then write
    tf = load_trackform(args.trackform) if args.trackform else check_trackform(Trackform(), "thesis Table 2.2")
    source = str(args.trackform) if args.trackform else "thesis Table 2.2"
    f = np.arange(TRACK_BAND_HZ[0], TRACK_BAND_HZ[1] + 0.5 * args.df, args.df)
    f = f[f <= TRACK_BAND_HZ[1] * (1 + 1e-12)]
    v = track_receptance(f, tf, "vertical", supports=args.supports)
    lat = track_receptance(f, tf, "lateral", supports=args.supports)
    for name, h in (("vertical", v), ("lateral", lat)):
        bad = ~np.isfinite(h)
        if bad.any():
            raise TrackformError(f"{source}: the {name} receptance is not finite at {f[bad][0]:g} Hz with these "
                                 f"parameters; check the trackform's values")
    df = pd.DataFrame({"f_hz": f, "vertical_re": v.real, "vertical_im": v.imag, "lateral_re": lat.real,
                       "lateral_im": lat.imag})
    supports = ("continuous", "discrete") if args.supports == "discrete" else ("continuous",)
    fig = plot_track_receptance(f, tf, supports=supports)
    out = Path(args.out)
    with staged_output(out) as tmp:
        df.to_csv(tmp / "track_receptance.csv", index=False, float_format="%.9e")
        fig.savefig(tmp / "track_receptance.png", dpi=120)
    plt.close(fig)
    above = f > 20
    for name, h in (("vertical", v), ("lateral", lat)):
        k = int(np.argmax(np.where(above, np.abs(h), -np.inf))) if above.any() else int(np.argmax(np.abs(h)))
        print(f"{name:8s}: static {abs(h[0]):.3e} m/N at {f[0]:g} Hz; largest above 20 Hz {abs(h[k]):.3e} m/N "
              f"at {f[k]:g} Hz")
    print(f"pinned-pinned (exact Timoshenko span): {pinned_pinned_frequency(tf):.1f} Hz")
    print(f"written: {out / 'track_receptance.csv'} ({len(df)} lines, {args.supports} supports), "
          f"{out / 'track_receptance.png'}")
    return 0


def _keep_fe(text: str):
    if text in ("none", "unpaired", "all"):
        return text
    try:
        return [int(t) for t in text.replace(" ", "").split(",") if t]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--keep-fe takes none, unpaired, all or FE mode numbers like 20,21; "
                                         f"got {text!r}") from None


#: Most hammer files ``model build`` validates against, and most perturbed models of the robustness study.
MAX_VALIDATION_FILES = 8
MAX_ROBUSTNESS_MODELS = 5000


def _cmd_build(args: argparse.Namespace) -> int:
    import fem_import
    from ema.channels import read_channels
    from fem_import.modes import shapes_at_channels
    from receptance.dofs import check_points, read_points
    from receptance.frame import to_railway_frame
    from receptance.hybrid import check_fe_for_model, hybrid_model
    from receptance.modal_model import ModelError
    from receptance.model_io import save_model
    from receptance.plot_model import plot_receptances

    from railmodal.output import staged_output

    plt = _agg()
    step = _progress(args.quiet)
    hammers, channels = list(args.hammer or []), list(args.channels or [])
    if len(hammers) != len(channels):
        args._build_parser.error(f"each --hammer needs its --channels (in the same order): got {len(hammers)} "
                                 f"--hammer and {len(channels)} --channels")
    if len(hammers) > MAX_VALIDATION_FILES:
        args._build_parser.error(f"at most {MAX_VALIDATION_FILES} --hammer files, got {len(hammers)}")
    # ---- validate every input before any work
    suspension, suspension_source = _primary_suspension(args.description)
    step(f"reading {args.fem}")
    fe, where = fem_import.read_with_geometry(args.fem, args.geometry, units=args.fe_units)
    step(where)
    rb = check_fe_for_model(fe, total_mass=args.total_mass)
    if rb is not None:
        step(f"rigid-body modes: total mass {rb.mass:.1f} kg (mass-normalised shapes)")
    points = read_points(args.points)
    check_points(fe, points, source=str(args.points))
    tables = [read_channels(c) for c in channels]
    # the model is built in the railway frame the points define, whatever the FE's frame (receptance.frame); the
    # hammer files are read with their tables as written, and compared in that frame
    frame, points, fe, rail_tables, _ = to_railway_frame(points, fe, tables=tables, source=str(args.points))
    if not frame.is_identity:
        step(frame.describe())
    free = hybrid_model(fe, args.pairing, points=points, keep_fe=args.keep_fe, default_zeta=args.default_zeta)
    if args.diagnosed is not None:  # the lab's diagnosed model: its wheelset properties, not its test artefacts
        from receptance.model_io import load_service_model

        free = load_service_model(args.diagnosed, fe=fe)
    for table in rail_tables:
        shapes_at_channels(free.fe, table)  # every sensor near its fe_node (named in the error)
    # ---- work
    # the wheelset's own (FE/test) modes are lightly damped structural modes: one overdamped or not finite means
    # bad shapes or units, not physics; the suspended rigid-body modes may well be overdamped (a light wheelset on
    # stiff dampers), which is reported, not refused
    elastic = free.modes()
    bad = ~np.isfinite(elastic["f_hz"].to_numpy(float)) | (elastic["zeta"].to_numpy(float) >= 1)
    if bad.any():
        r = elastic[bad].iloc[0]
        raise ModelError(f"the wheelset model built from {args.fem} has an elastic mode at {r['f_hz']:.4g} Hz with "
                         f"damping ratio {r['zeta']:.3g}: not a structure; check the FE export's normalisation and "
                         f"units")
    model = free if args.free_free else free.with_modification(suspension)
    system_modes = model.modes()
    if not np.isfinite(system_modes[["f_hz", "zeta"]].to_numpy(float)).all():
        raise ModelError(f"the in-service model (primary suspension from {suspension_source}) has a mode that is "
                         f"not finite; check the suspension's values")
    overdamped = system_modes[system_modes["zeta"].to_numpy(float) >= 1]
    state = "free-free" if args.free_free else f"in service (primary suspension, {suspension_source})"
    f = np.linspace(args.band[0], args.band[1], 2000)
    step("receptances between contact points and axleboxes")
    H = model.receptance(["contact_L:z", "axlebox_L:z", "contact_R:z", "axlebox_R:z", "contact_L:y",
                          "axlebox_L:y"], ["contact_L:z", "contact_L:y"], f)
    out = Path(args.out)
    with staged_output(out) as tmp:
        path = save_model(model, tmp / "hybrid_model.npz")
        free.table.to_csv(tmp / "modes.csv", index=False, float_format="%.6g")
        system_modes.to_csv(tmp / "system_modes.csv", index=False, float_format="%.6g")
        fig = plot_receptances(H, [("contact_L:z", "contact_L:z"), ("axlebox_L:z", "contact_L:z"),
                                   ("contact_R:z", "contact_L:z"), ("axlebox_R:z", "contact_L:z"),
                                   ("contact_L:y", "contact_L:y"), ("axlebox_L:y", "contact_L:y")],
                               title=f"wheelset receptances, {state}")
        fig.savefig(tmp / "receptances.png", dpi=120)
        plt.close(fig)
        written = [path, tmp / "modes.csv", tmp / "system_modes.csv", tmp / "receptances.png"]
        written += _transfer_plots(model, f, args, tmp, step)
        lines = []
        for hammer, table, rail_table in zip(hammers, tables, rail_tables):
            paths, line = _validation(free, hammer, table, rail_table, tmp, step)
            written += paths
            lines.append(line)
        written = [out / p.relative_to(tmp) for p in written]
    print(free.table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"{state}: lowest modes " + ", ".join(f"{r.f_hz:.2f} Hz (zeta {100 * r.zeta:.1f} %)"
                                                 for r in system_modes.head(6).itertuples()))
    if len(overdamped):
        print("overdamped suspension motion (real poles, no oscillation; |λ|/2π): " + ", ".join(
            f"{r.f_hz:.2f} Hz" for r in overdamped.itertuples()) + " — the primary suspension's dampers exceed "
            "critical damping on a rigid-body motion of this wheelset (physics, not an error)")
    for line in lines:
        print(line)
    print("written: " + ", ".join(str(p) for p in written))
    return 0


def _primary_suspension(description):
    """The in-service primary suspension: the description's ``[primary_suspension]`` or thesis Table 2.1.

    Returns the modification and where its values come from (for the output).
    """
    from receptance.modification import PrimarySuspension
    from receptance.wheelset_description import read_description

    if description is None:
        return PrimarySuspension(), "thesis Table 2.1"
    d = read_description(description)
    given = {k: v for k, v in (("stiffness", d.suspension_stiffness), ("damping", d.suspension_damping))
             if v is not None}
    if not given:
        return PrimarySuspension(), f"thesis Table 2.1 ({description} has no [primary_suspension])"
    rest = "" if len(given) == 2 else f", {'damping' if 'stiffness' in given else 'stiffness'} of Table 2.1"
    return PrimarySuspension(**given), f"{description}{rest}"


def _transfer_plots(model, f, args, out: Path, step) -> list[Path]:
    """Thesis Figs. 4.1–4.7: half-model receptances, the three transfer functions, their spectral spread."""
    import numpy as np

    from receptance.plot_transfer import plot_half_receptances, plot_spectral_std, plot_transfer
    from receptance.robustness import robustness_study
    from receptance.transfer import full_vertical_transfer, half_wheelset_transfer, vertical_lateral_transfer

    plt = _agg()
    theta_l, theta_r = np.radians(args.theta)
    f = f[f > 0]
    step("transfer functions: half wheelset (eq. 2.6), full vertical (2.11), vertical + lateral (2.22)")
    models = {
        "half": half_wheelset_transfer(model, f, side="L"),
        "vertical": full_vertical_transfer(model, f),
        "vertical_lateral": vertical_lateral_transfer(model, f, theta_l=theta_l, theta_r=theta_r),
    }
    written = []
    fig = plot_half_receptances(models["half"])
    fig.savefig(out / "fig4_1_half_receptances.png", dpi=120)
    plt.close(fig)
    written.append(out / "fig4_1_half_receptances.png")
    for k, (name, tf) in enumerate(models.items()):
        fig = plot_transfer(tf)
        path = out / f"fig4_{k + 2}_transfer_{name}.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)
    step(f"robustness: {args.robustness_models} models with modal frequencies and damping varied ±10 % (thesis §4.2)")
    study = robustness_study(model, f, n_models=args.robustness_models, theta_l=theta_l, theta_r=theta_r, seed=0)
    for k, name in enumerate(study.models):
        fig = plot_spectral_std(study, name)
        path = out / f"fig4_{k + 5}_spectral_std_{name}.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)
    return written


def _validation(model, hammer, table, rail_table, out: Path, step) -> tuple[list[Path], str]:
    from ema import estimate_frf, read_hammer
    from receptance.compare import compare_frf
    from receptance.plot_model import plot_channel_errors, plot_comparison

    plt = _agg()
    step(f"validating the free-free model against {hammer}")
    test = read_hammer(hammer, table)
    H = estimate_frf(test)
    c = compare_frf(model, H, rail_table)
    stem = Path(hammer).stem
    c.channels.to_csv(out / f"validation_{stem}.csv", index=False, float_format="%.6g")
    fig = plot_comparison(c)
    fig.savefig(out / f"validation_{stem}_worst.png", dpi=110)
    plt.close(fig)
    fig = plot_channel_errors(c)
    fig.savefig(out / f"validation_{stem}_errors.png", dpi=110)
    plt.close(fig)
    line = (f"{stem}: model vs measurement {c.band_hz[0]:g}–{c.band_hz[1]:g} Hz, median {c.summary_db:.2f} dB RMS, "
            f"complex error median {100 * c.channels['rel_error'].median():.2f} %, worst channel "
            f"{c.channels.sort_values('db_rms').iloc[-1]['channel']}")
    return [out / f"validation_{stem}.csv", out / f"validation_{stem}_worst.png",
            out / f"validation_{stem}_errors.png"], line


def add_model_commands(sub) -> None:
    """Register ``railmodal model track`` and ``railmodal model build`` on the top-level subparsers.

    Every option is typed and bounded (:mod:`railmodal.arguments`): a bad value stops the command before any work
    with a message naming the option, its range and the value.
    """
    model = sub.add_parser("model", help="track receptance and hybrid wheelset model")
    msub = model.add_subparsers(dest="model_command", required=True)
    tr = msub.add_parser("track", help="rail point receptances (thesis §2.4) -> track_receptance.csv and plot")
    tr.add_argument("--trackform", default=None, type=existing_file("--trackform", "trackform (TOML/JSON)"),
                    help="TOML/JSON trackform file (default: thesis Table 2.2)")
    tr.add_argument("--supports", choices=("continuous", "discrete"), default="continuous",
                    help="continuous two-layer support (default) or discrete supports every L_s (mid-span)")
    tr.add_argument("--df", type=bounded_float("--df", 0.0, 100.0, lo_open=True, unit="Hz", check=_track_lines), default=1.0,
                    help=f"frequency step [Hz] over {TRACK_BAND_HZ[0]:g}–{TRACK_BAND_HZ[1]:g} Hz, at most 100 Hz and at "
                         f"most {MAX_TRACK_LINES} lines (default 1)")
    tr.add_argument("--out", required=True, type=output_folder("--out"))
    tr.set_defaults(func=_cmd_track)
    b = msub.add_parser("build", help="hybrid wheelset model from a pairing (thesis §2.3) + transfer functions")
    b.add_argument("--pairing", required=True,
                   type=existing_folder("--pairing", "pairing (folder of 'railmodal lab pair' or its pairing.csv)",
                                        file_ok=True),
                   help="folder (or CSV) written by 'railmodal lab pair'")
    b.add_argument("--fem", required=True, type=existing_file("--fem", "FE modes"),
                   help="the FE modes file the pairing used (UFF 2411/2412 with 55 or 2414, Nastran .pch, "
                        ".f06, .op2 or .h5, an ANSYS .rst or a CalculiX .frd)")
    add_geometry_argument(b)
    b.add_argument("--points", required=True, type=existing_file("--points", "points table"),
                   help="points table CSV: name, fe_node, x, y, z (contact_L, axlebox_L...)")
    b.add_argument("--total-mass", type=bounded_float("--total-mass", 0.0, 1e6, lo_open=True, unit="kg"),
                   default=None, help="the wheelset's mass [kg] to check the FE shapes' mass normalisation against "
                                      "(default: the physical range of a railway wheelset)")
    b.add_argument("--keep-fe", type=_keep_fe, default="none",
                   help="FE-only modes to keep: none (thesis Table 3.1 policy), unpaired, all, or numbers 20,21")
    b.add_argument("--default-zeta", type=bounded_float("--default-zeta", 0.0, 1.0, hi_open=True), default=1e-3,
                   help="damping ratio of kept FE-only modes, in [0, 1) (default 0.001)")
    b.add_argument("--diagnosed", default=None, type=existing_file("--diagnosed", "diagnosed model"),
                   help="hybrid_model.npz of 'lab diagnose' (same FE export): the model keeps the wheelset "
                        "properties the diagnosis found (bearings, press fits), not its test artefacts (rig, sensors)")
    b.add_argument("--description", type=existing_file("--description", "wheelset description (TOML)"),
                   default=None, help="wheelset description (TOML); its [primary_suspension] (stiffness_N_per_m, "
                                      "damping_N_s_per_m per axlebox along x, y, z) is the in-service suspension "
                                      "(default: thesis Table 2.1)")
    b.add_argument("--free-free", action="store_true", help="do not add the primary suspension")
    b.add_argument("--band", nargs=2, type=bounded_float("--band", 0.0, 1e5, lo_open=True, unit="Hz"),
                   action=band_action("--band", 0.0, 1e5), default=[1.0, 500.0], metavar=("LOW", "HIGH"),
                   help="frequency range of the plots [Hz], 0 < LOW < HIGH <= 1e5 (default 1 500)")
    b.add_argument("--theta", nargs=2, type=bounded_float("--theta", -90.0, 90.0, lo_open=True, hi_open=True,
                                                          unit="deg"),
                   default=[0.0, 0.0], metavar=("LEFT", "RIGHT"),
                   help="contact-plane angles θ_L, θ_R [deg] in (-90, 90) for the vertical+lateral model (eq. 2.12)")
    b.add_argument("--robustness-models", type=bounded_int("--robustness-models", 2, MAX_ROBUSTNESS_MODELS),
                   default=50, help=f"perturbed models of the robustness study, 2 to {MAX_ROBUSTNESS_MODELS} "
                                    f"(thesis §4.2: 50)")
    b.add_argument("--hammer", action="append", type=existing_file("--hammer", "hammer-test (UFF58, MDF, TDMS or CSV)"),
                   help="optional: hammer-test file (UFF58, MDF, TDMS or CSV) to validate the model against")
    b.add_argument("--channels", action="append", type=existing_file("--channels", "channel table"),
                   help="channel table of each --hammer file")
    b.add_argument("--out", required=True, type=output_folder("--out"))
    b.set_defaults(func=_cmd_build, _build_parser=b)
