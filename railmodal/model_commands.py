"""``railmodal model ...``: track receptance and hybrid wheelset model from the command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

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


def _cmd_track(args: argparse.Namespace) -> int:
    import numpy as np
    import pandas as pd

    from receptance.plot_track import plot_track_receptance
    from receptance.track import pinned_pinned_frequency, track_receptance
    from receptance.trackform import Trackform, load_trackform

    plt = _agg()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tf = load_trackform(args.trackform) if args.trackform else Trackform()
    f = np.arange(1.0, 2000.0 + 0.5 * args.df, args.df)
    v = track_receptance(f, tf, "vertical", supports=args.supports)
    lat = track_receptance(f, tf, "lateral", supports=args.supports)
    df = pd.DataFrame({"f_hz": f, "vertical_re": v.real, "vertical_im": v.imag, "lateral_re": lat.real,
                       "lateral_im": lat.imag})
    df.to_csv(out / "track_receptance.csv", index=False, float_format="%.9e")
    supports = ("continuous", "discrete") if args.supports == "discrete" else ("continuous",)
    fig = plot_track_receptance(f, tf, supports=supports)
    fig.savefig(out / "track_receptance.png", dpi=120)
    plt.close(fig)
    for name, h in (("vertical", v), ("lateral", lat)):
        k = np.argmax(np.abs(h) * (f > 20))
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


def _cmd_build(args: argparse.Namespace) -> int:
    import numpy as np

    import fem_import
    from receptance.dofs import read_points
    from receptance.hybrid import hybrid_model
    from receptance.model_io import save_model
    from receptance.modification import PrimarySuspension
    from receptance.plot_model import plot_receptances

    plt = _agg()
    step = _progress(args.quiet)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    step(f"reading {args.fem}")
    fe = fem_import.read(args.fem)
    points = read_points(args.points)
    free = hybrid_model(fe, args.pairing, points=points, keep_fe=args.keep_fe, default_zeta=args.default_zeta)
    model = free if args.free_free else free.with_modification(PrimarySuspension())
    path = save_model(model, out / "hybrid_model.npz")
    free.table.to_csv(out / "modes.csv", index=False, float_format="%.6g")
    system_modes = model.modes()
    system_modes.to_csv(out / "system_modes.csv", index=False, float_format="%.6g")
    print(free.table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    state = "free-free" if args.free_free else "in service (primary suspension, thesis Table 2.1)"
    print(f"{state}: lowest modes " + ", ".join(f"{r.f_hz:.2f} Hz (zeta {100 * r.zeta:.1f} %)"
                                                 for r in system_modes.head(6).itertuples()))
    f = np.linspace(args.band[0], args.band[1], 2000)
    step("receptances between contact points and axleboxes")
    H = model.receptance(["contact_L:z", "axlebox_L:z", "contact_R:z", "axlebox_R:z", "contact_L:y",
                          "axlebox_L:y"], ["contact_L:z", "contact_L:y"], f)
    fig = plot_receptances(H, [("contact_L:z", "contact_L:z"), ("axlebox_L:z", "contact_L:z"),
                               ("contact_R:z", "contact_L:z"), ("axlebox_R:z", "contact_L:z"),
                               ("contact_L:y", "contact_L:y"), ("axlebox_L:y", "contact_L:y")],
                           title=f"wheelset receptances, {state}")
    fig.savefig(out / "receptances.png", dpi=120)
    plt.close(fig)
    written = [path, out / "modes.csv", out / "system_modes.csv", out / "receptances.png"]
    written += _transfer_plots(model, f, args, out, step)
    for hammer, channels in zip(args.hammer or [], args.channels or []):
        written += _validation(free, hammer, channels, out, step)
    print("written: " + ", ".join(str(p) for p in written))
    return 0


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


def _validation(model, hammer: str, channels: str, out: Path, step) -> list[Path]:
    import pandas as pd

    from ema import estimate_frf, read_hammer
    from receptance.compare import compare_frf
    from receptance.plot_model import plot_channel_errors, plot_comparison

    plt = _agg()
    step(f"validating the free-free model against {hammer}")
    test = read_hammer(hammer, channels)
    H = estimate_frf(test)
    table = pd.read_csv(channels)
    c = compare_frf(model, H, table)
    stem = Path(hammer).stem
    c.channels.to_csv(out / f"validation_{stem}.csv", index=False, float_format="%.6g")
    fig = plot_comparison(c)
    fig.savefig(out / f"validation_{stem}_worst.png", dpi=110)
    plt.close(fig)
    fig = plot_channel_errors(c)
    fig.savefig(out / f"validation_{stem}_errors.png", dpi=110)
    plt.close(fig)
    print(f"{stem}: model vs measurement {c.band_hz[0]:g}–{c.band_hz[1]:g} Hz, median {c.summary_db:.2f} dB RMS, "
          f"complex error median {100 * c.channels['rel_error'].median():.2f} %, worst channel "
          f"{c.channels.sort_values('db_rms').iloc[-1]['channel']}")
    return [out / f"validation_{stem}.csv", out / f"validation_{stem}_worst.png", out / f"validation_{stem}_errors.png"]


def add_model_commands(sub) -> None:
    """Register ``railmodal model track`` and ``railmodal model build`` on the top-level subparsers."""
    model = sub.add_parser("model", help="track receptance and hybrid wheelset model")
    msub = model.add_subparsers(dest="model_command", required=True)
    tr = msub.add_parser("track", help="rail point receptances (thesis §2.4) -> track_receptance.csv and plot")
    tr.add_argument("--trackform", default=None, help="TOML/JSON trackform file (default: thesis Table 2.2)")
    tr.add_argument("--supports", choices=("continuous", "discrete"), default="continuous",
                    help="continuous two-layer support (default) or discrete supports every L_s (mid-span)")
    tr.add_argument("--df", type=float, default=1.0, help="frequency step [Hz] over 1–2000 Hz (default 1)")
    tr.add_argument("--out", required=True)
    tr.set_defaults(func=_cmd_track)
    b = msub.add_parser("build", help="hybrid wheelset model from a pairing (thesis §2.3) + transfer functions")
    b.add_argument("--pairing", required=True, help="folder (or CSV) written by 'railmodal lab pair'")
    b.add_argument("--fem", required=True, help="the FE modes file the pairing used")
    b.add_argument("--points", required=True, help="points table CSV: name, fe_node, x, y, z (contact_L, axlebox_L...)")
    b.add_argument("--keep-fe", type=_keep_fe, default="none",
                   help="FE-only modes to keep: none (thesis Table 3.1 policy), unpaired, all, or numbers 20,21")
    b.add_argument("--default-zeta", type=float, default=1e-3, help="damping ratio of kept FE-only modes")
    b.add_argument("--free-free", action="store_true", help="do not add the primary suspension")
    b.add_argument("--band", nargs=2, type=float, default=[1.0, 500.0], metavar=("LOW", "HIGH"),
                   help="frequency range of the plots [Hz]")
    b.add_argument("--theta", nargs=2, type=float, default=[0.0, 0.0], metavar=("LEFT", "RIGHT"),
                   help="contact-plane angles θ_L, θ_R [deg] for the vertical+lateral model (eq. 2.12)")
    b.add_argument("--robustness-models", type=int, default=50,
                   help="perturbed models of the robustness study (thesis §4.2: 50)")
    b.add_argument("--hammer", action="append", help="optional: hammer-test UFF to validate the model against")
    b.add_argument("--channels", action="append", help="channel table of each --hammer file")
    b.add_argument("--out", required=True)
    b.set_defaults(func=_cmd_build)
