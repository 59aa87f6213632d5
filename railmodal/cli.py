"""The ``railmodal`` command line.

``railmodal demo``                      simulate a virtual-lab campaign and run the whole lab workflow on it (report)
``railmodal lab simulate``              write a campaign of one scenario (``--scenario NAME --out DIR``)
``railmodal lab simulate-line``         write a virtual-line campaign (``--scenario NAME --days N --runs-per-day M --out DIR``)
``railmodal lab scenarios``             list the virtual-lab scenarios
``railmodal lab render``                pictures of the design wheelset and its modes
``railmodal lab identify``              hammer-test or FRF files -> identified modes, stabilisation and FRF plots
``railmodal lab pair``                  identified modes + FE export -> pairing table (thesis Table 3.1) and renders
``railmodal lab diagnose``              hammer tests + FE export -> identify, pair, hybrid model, compare, diagnose;
                                        diagnosis.json and report.html
``railmodal model track``               rail point receptances (thesis §2.4) -> track_receptance.csv and plot
``railmodal model build``               pairing + FE export + points -> hybrid wheelset model, transfer functions
``railmodal field estimate``            one field run (MDF 4) + sensor table + hybrid model -> rail roughness per rail,
                                        EN 13231-3 indexes, EN 15610 spectra, report
``railmodal field ingest``              runs -> monitoring store (aligned, averaged, intervals; Dask)
``railmodal field monitor``             store -> trends, grinding events, forecast table, HTML report
``railmodal field compare-reference``   trolley records against the train's day averages, band errors per rail
``railmodal field reprocess``           the store's runs again with a new wheelset model (both versions kept)
``railmodal field diagnose``            calibration site runs + trolley -> missing field effects fitted, ranked,
                                        validated; field_diagnosis.json, report.html, calibrated model
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from ema.limits import MAX_ORDER
from railmodal.arguments import add_geometry_argument, band_action, bounded_float, bounded_int, existing_file, existing_folder, output_folder
from railmodal.diagnose_command import add_diagnose_parser, summarise
from railmodal.field_commands import add_field_commands
from railmodal.field_diagnose_command import add_field_diagnose_command
from railmodal.line_commands import add_line_commands
from railmodal.model_commands import add_model_commands
from railmodal.monitor_commands import add_monitor_commands

__all__ = ["main"]

#: Most --hammer files of one setup in 'lab identify' (one hit per file is common; tens of hits make a setup).
MAX_HAMMER_FILES = 200


def _scenario_names() -> list[str]:
    from lab_data.scenarios import SCENARIOS

    return sorted(SCENARIOS)


def _design_names() -> list[str]:
    from lab_data.designs import DESIGNS

    return sorted(DESIGNS)


def _setup_logging(verbosity: int) -> None:
    level = logging.WARNING if verbosity < 0 else logging.INFO if verbosity == 0 else logging.DEBUG
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(message)s", datefmt="%H:%M:%S",
                        stream=sys.stderr)


def _progress(msg: str) -> None:
    print(f"  … {msg}", file=sys.stderr, flush=True)


def _describe_campaign(files: dict[str, Path], brief: bool = False) -> None:
    import json

    manifest = json.loads(files["truth"].read_text())
    if brief:
        size = sum(p.stat().st_size for p in files.values())
        folder = files["truth"].parent
        print(f"campaign: {len(files)} files ({size / 1e6:.1f} MB) in {folder}: "
              + ", ".join(p.name for p in files.values()))
        print(f"scenario: {manifest['scenario']['name']} — {manifest['scenario']['description']}")
        return
    print("files written:")
    for key, path in files.items():
        size = path.stat().st_size
        print(f"  {key:20s} {path}  ({size / 1e6:.2f} MB)")
    print(f"scenario: {manifest['scenario']['name']} — {manifest['scenario']['description']}")
    for name, setup in manifest["setups"].items():
        seen = [m for m in setup["modes"] if m["observable"]]
        print(f"setup {name}: {len(setup['hits'])} hits, double hit(s) {setup['double_hits']}, "
              f"clipped {[(c['hit'], c['node']) for c in setup['clipped']]}; "
              f"{len(seen)} truth modes observable in {manifest['band_hz'][0]:g}–{manifest['band_hz'][1]:g} Hz:")
        for m in seen:
            print(f"    {m['f_hz']:8.2f} Hz  zeta {100 * m['zeta']:.3f} %  {m['description']}")


def _cmd_simulate(args: argparse.Namespace) -> int:
    from lab_data.campaign import simulate
    from lab_data.designs import DESIGN_FE_MAX_HZ

    from railmodal.output import staged_output

    t0 = time.perf_counter()
    with staged_output(args.out) as tmp:
        fe_max_hz = DESIGN_FE_MAX_HZ[args.design] if args.fe_max_hz is None else args.fe_max_hz
        written = simulate(args.scenario, tmp, progress=None if args.quiet else _progress, design=args.design,
                           fe_max_hz=fe_max_hz, fe_export_hz=args.fe_export_hz, fe_style=args.fe_style,
                           seed=args.seed, n_hits=args.hits, hammer_scatter_deg=args.hammer_scatter)
    files = {key: Path(args.out) / path.relative_to(tmp) for key, path in written.items()}
    _describe_campaign(files)
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def _cmd_scenarios(args: argparse.Namespace) -> int:
    from lab_data.scenarios import SCENARIOS

    for name in sorted(SCENARIOS):
        print(f"{name:12s} {SCENARIOS[name].description}")
    return 0


def _render(out: Path, n_modes: int, quiet: bool) -> list[Path]:
    from lab_data.plot import render_wheelset
    from lab_data.truth import design_modes
    from lab_data.wheelset import WheelsetParameters

    design = design_modes(WheelsetParameters(), 500.0)
    paths = [render_wheelset(design.model, out / "wheelset.png", title="railmodal design wheelset")]
    shown = 0
    seen = set()
    for i, (f, lab) in enumerate(zip(design.modes.freqs_hz, design.labels)):
        # one picture per mode, not per member of a degenerate pair
        if lab.family == "rigid" or (lab.family, lab.order) in seen:
            continue
        if shown >= n_modes:
            break
        seen.add((lab.family, lab.order))
        name = f"mode_{shown + 1:02d}_{f:.0f}Hz.png"
        paths.append(render_wheelset(design.model, out / name, shape=design.modes.shapes[i],
                                     title=f"{lab.description}  {f:.1f} Hz"))
        shown += 1
        if not quiet:
            _progress(f"rendered {name}")
    return paths


def _cmd_render(args: argparse.Namespace) -> int:
    paths = _render(Path(args.out), args.modes, args.quiet)
    for p in paths:
        print(p)
    return 0


def _cmd_identify(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import ema
    from ema.driving_point import driving_point_checks, driving_point_findings
    from ema.modes_io import write_modeset
    from ema.plot import plot_stabilisation, plot_synthesis

    from railmodal.output import check_output_folder, staged_output

    out = check_output_folder(args.out)
    band = tuple(args.band)
    hammers, frfs, tables = _identify_inputs(args)
    t0 = time.perf_counter()
    step = (lambda msg: None) if args.quiet else _progress
    if frfs:  # FRFs exported by the acquisition system: nothing to screen or average
        step(f"reading FRFs {frfs[0]}")
        table = ema.read_channels(tables[0])
        frf = ema.read_frf_uff(frfs[0], table, exp_window_decay=args.window_decay)
        frf = frf.as_quantity("accelerance").select(band_hz=band)
        screening = None
        full_table = table
        named = "setup" in table and table["setup"].notna().any()
        setup = args.setup or (str(table["setup"].dropna().iloc[0]) if named else Path(frfs[0]).stem)
    else:
        step(f"reading {hammers[0]}" if len(hammers) == 1 else
             f"reading {len(hammers)} files of one setup ({hammers[0]} ... {hammers[-1]})")
        test = ema.read_hammer(hammers if len(hammers) > 1 else hammers[0], tables[0])
        step(f"{len(test.hits)} hits x {test.responses.shape[1]} channels at {test.fs:g} Hz; screening hits and "
             f"estimating H1 in {band[0]:g}-{band[1]:g} Hz")
        screening = ema.screen_hits(test, band_hz=band)
        frf = ema.estimate_frf(test, band_hz=band, screening=screening)
        full_table = test.channels
        setup = args.setup or _setup_name(test, Path(hammers[0]))
    step(f"identifying (LSCE to order {args.max_order}, automatic pole selection, LSFD)")
    result = ema.identify(frf, band_hz=band, max_order=args.max_order, setup=setup)
    modes = result.modes
    checks = driving_point_checks(modes, full_table)
    for finding in driving_point_findings(checks, source=setup):
        logging.getLogger("ema").warning("%s", finding)
    with staged_output(out) as tmp:  # write last: --out gets the results only when everything succeeded
        write_modeset(modes, tmp)
        fig = plot_stabilisation(result.diagram, frf=frf)
        fig.savefig(tmp / "stabilisation.png", dpi=120)
        plt.close(fig)
        fig = plot_synthesis(frf, result.synthesis)
        fig.savefig(tmp / "synthesis.png", dpi=120)
        plt.close(fig)
        if screening is not None:
            screening.to_frame().to_csv(tmp / "screening.csv", index=False)
    for r in (screening.rejections if screening is not None else ()):
        print(f"rejected: {r}")
    print(f"{len(modes)} modes identified in {setup!r} ({time.perf_counter() - t0:.1f} s):")
    for f, z, m in zip(modes.freqs_hz, modes.zeta, modes.mpc):
        print(f"  {f:9.3f} Hz  zeta {100 * z:.4f} %  MPC {m:.3f}")
    for c in checks:
        print(f"driving point {c.channel!r}: {c.verdict} ({c.n_modes - c.n_wrong} of {c.n_modes} modal constants of "
              f"the sign a driving point must have)")
    print(f"written: {out / 'modes.csv'}, {out / 'modes.uff'}, {out / 'stabilisation.png'}, {out / 'synthesis.png'}"
          + (f", {out / 'screening.csv'}" if screening is not None else ""))
    return 0


def _identify_inputs(args: argparse.Namespace) -> tuple[list[str], list[str], list[str]]:
    """The --hammer files, --frf files and --channels tables of ``lab identify``, checked before any reading.

    Several --hammer files are the hits of one setup (one hit per file): read as one test with one channel
    table. Repeated --frf or different --channels are refused (argparse error, exit status 2): the last one
    would otherwise be used silently.
    """
    parser = args._identify_parser
    hammers, frfs, tables = list(args.hammer or []), list(args.frf or []), list(args.channels or [])
    if len(frfs) > 1:
        parser.error(f"--frf given {len(frfs)} times; 'lab identify' reads one FRF file (a setup's FRFs as the "
                     f"front end exported them): identify each file on its own")
    if len(hammers) > MAX_HAMMER_FILES:
        parser.error(f"--hammer given {len(hammers)} times; at most {MAX_HAMMER_FILES} files make one test")
    seen: dict = {}
    for k, h in enumerate(hammers):
        key = Path(h).resolve()
        if key in seen:
            parser.error(f"--hammer {h} is given twice (files {seen[key] + 1} and {k + 1}); its hits would be "
                         f"averaged in twice")
        seen[key] = k
    if len({Path(c).resolve() for c in tables}) > 1:
        contents = {Path(c).read_bytes() for c in tables}
        if len(contents) > 1:
            parser.error(f"--channels given {len(tables)} times with different tables "
                         f"({', '.join(map(str, tables))}); 'lab identify' identifies one setup: give its one channel "
                         f"table (several --hammer files of the setup share it)")
    if args.window_decay is not None and not frfs:
        parser.error("--window-decay is the decay of the exponential window a front end applied to --frf files; "
                     "with --hammer the toolkit chooses its own window and corrects the damping for it")
    return hammers, frfs, tables


def _setup_name(test, path: Path) -> str:
    ch = test.channels
    if "setup" in ch and ch["setup"].notna().any():
        return str(ch["setup"].dropna().iloc[0])
    return path.stem


def _cmd_pair(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import fem_import
    from ema.merge import merge_setups
    from ema.modes_io import read_modeset
    from ema.pairing import pair_modes
    from ema.plot_pairing import plot_mac, render_pair
    from ema.polarity import channel_polarity, polarity_findings

    from railmodal.output import staged_output

    out = Path(args.out)
    step = (lambda msg: None) if args.quiet else _progress
    sets = [read_modeset(d) for d in args.modes]
    test = merge_setups(sets) if len(sets) > 1 else sets[0]
    step(f"{len(test)} test modes from {len(sets)} setup(s); reading {args.fem}")
    fe, where = fem_import.read_with_geometry(args.fem, args.geometry, units=args.fe_units)
    step(where)
    pairing = pair_modes(test, fe, threshold=args.mac_min)
    polarity = channel_polarity(test, fe, pairing)
    with staged_output(out) as tmp:  # write last: --out gets the results only when everything succeeded
        pairing.to_csv(tmp / "pairing.csv")
        polarity.to_csv(tmp / "channel_polarity.csv", index=False, float_format="%.6g")
        fig = plot_mac(pairing, test, fe)
        fig.savefig(tmp / "mac.png", dpi=120)
        plt.close(fig)
        for k, p in enumerate(pairing.pairs):
            name = f"pair_{k + 1:02d}_{test.freqs_hz[p.test_index]:.0f}Hz.png"
            fe_label = "+".join(str(j + 1) for j in p.fe_indices)
            render_pair(test, p.test_index, fe, p.fe_shape, tmp / name,
                        title=f"FE mode {fe_label}: {fe.freqs_hz[p.fe_indices[0]]:.2f} Hz, MAC {p.mac:.3f}")
            step(f"rendered {name}")
    print(pairing.table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    for finding in polarity_findings(polarity):
        logging.getLogger("ema").warning("%s", finding)
    print(f"written: {out / 'pairing.csv'}, {out / 'channel_polarity.csv'}, {out / 'mac.png'} and "
          f"{len(pairing.pairs)} renders")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from lab_data.campaign import simulate

    out = Path(args.out)
    step = (lambda msg: None) if args.quiet else _progress
    print(f"railmodal demo: simulating a virtual-lab impact-test campaign (scenario {args.scenario!r}) into {out}")
    t0 = time.perf_counter()
    files = simulate(args.scenario, out, progress=step, fe_export_hz=2000.0)
    _describe_campaign(files, brief=not args.no_diagnose)
    pictures = _render(out / "pictures", 4, args.quiet)
    print(f"pictures: {len(pictures)} PNG in {out / 'pictures'}")
    if not args.no_diagnose:
        from receptance.diagnosis.workflow import run_lab_diagnosis

        print("running the lab workflow: identify -> pair -> hybrid model -> compare -> diagnose")
        setups = [(out / "flexural.uff", out / "flexural_channels.csv"),
                  (out / "torsional.uff", out / "torsional_channels.csv")]
        result = run_lab_diagnosis(setups, out / "fe_design.uff", out / "points.csv", out / "diagnosis",
                                   progress=step)
        for line in summarise(result):
            print(line)
        if not args.no_field:
            from railmodal.field_commands import demo_field_step

            print("field step: a short virtual-line run (curve 1) estimated with the model the lab workflow built")
            model = result.model if result.model is not None else result.paths["model"]
            for line in demo_field_step(out, model, args.scenario, step):
                print(line)
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="railmodal", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="simulate a virtual-lab campaign, run the whole lab workflow on it and "
                                       "write the diagnosis report")
    demo.add_argument("--out", default="railmodal-demo", help="output folder (default: ./railmodal-demo)")
    demo.add_argument("--scenario", default="rig", choices=_scenario_names(),
                      help="virtual-lab scenario (default: rig, whose hidden crane springs the diagnosis finds)")
    demo.add_argument("--no-diagnose", action="store_true", help="only simulate the campaign and render pictures")
    demo.add_argument("--no-field", action="store_true",
                      help="skip the field step (a short virtual-line run estimated with the lab's model)")
    demo.set_defaults(func=_cmd_demo)

    lab = sub.add_parser("lab", help="virtual wheelset lab")
    lab_sub = lab.add_subparsers(dest="lab_command", required=True)
    sim = lab_sub.add_parser("simulate", help="write the files of one impact-test campaign")
    sim.add_argument("--scenario", required=True, choices=_scenario_names())
    sim.add_argument("--out", required=True, type=output_folder("--out"), help="output folder")
    sim.add_argument("--design", choices=_design_names(), default="default",
                     help="the wheelset: default (thesis Table 2.1's metro trailer wheelset), metro (a light one, "
                          "180 kg wheels, r 0.34 m) or freight (a heavy one, 340 kg wheels, r 0.46 m); to check "
                          "that a workflow is not tuned to one wheelset")
    sim.add_argument("--fe-max-hz", type=bounded_float("--fe-max-hz", 50.0, 5000.0, unit="Hz"), default=None,
                     help="highest truth mode synthesised and, by default, exported (default: in the design's "
                          "spectral gap above 500 Hz: 500, metro 510, freight 520)")
    sim.add_argument("--fe-export-hz", type=bounded_float("--fe-export-hz", 50.0, 10000.0, unit="Hz"), default=None,
                     help="highest design FE mode exported if above --fe-max-hz (e.g. 2000: the basis structural "
                          "modifications such as bearings need)")
    sim.add_argument("--fe-style", choices=("mesh", "beam"), default="mesh",
                     help="style of the design FE export: mesh (the lab's 3D shell/beam mesh, default) or beam (a "
                          "design office's rotor-dynamics model: beam axle, lumped hubs, discs and axleboxes, rims "
                          "on web springs, its own node numbers); the hammer data are the same")
    sim.add_argument("--seed", type=bounded_int("--seed", 0, 2**32 - 1), default=1863,
                     help="random seed of hits and noise")
    sim.add_argument("--hits", type=bounded_int("--hits", 5, 100), default=6, help="hits per setup, 5 to 100")
    sim.add_argument("--hammer-scatter", type=bounded_float("--hammer-scatter", 0.0, 20.0, unit="degrees"),
                     default=0.0, metavar="DEG",
                     help="RMS tilt of each blow about the setup's hammer direction, drawn per hit (a hand-held "
                          "hammer's scatter, e.g. 3); default 0: every hit along one direction")
    sim.set_defaults(func=_cmd_simulate)
    sc = lab_sub.add_parser("scenarios", help="list the scenarios")
    sc.set_defaults(func=_cmd_scenarios)
    rd = lab_sub.add_parser("render", help="PNG pictures of the design wheelset and its first modes")
    rd.add_argument("--out", required=True, type=output_folder("--out"))
    rd.add_argument("--modes", type=bounded_int("--modes", 1, 60), default=6, help="modes rendered, 1 to 60 (default 6)")
    rd.set_defaults(func=_cmd_render)
    ident = lab_sub.add_parser("identify", help="identify modes from a hammer-test file or exported FRFs")
    source = ident.add_mutually_exclusive_group(required=True)
    source.add_argument("--hammer", action="append",
                        type=existing_file("--hammer", "hammer-test (UFF58, MDF, TDMS or CSV)"),
                        help="UFF58 time histories (one dataset per channel per hit), a DAQ's wide CSV export "
                             "(time, then one column per channel named as in --channels; a time column restarting, or "
                             "jumping between records of one length, is one hit per trigger), or a data logger's MDF "
                             "or NI TDMS file "
                             "(channels named as in --channels; one record per trigger, or one continuous record "
                             "cut into hits at the impacts); repeat it for a setup whose "
                             "hits are stored in several files (one hit per file): they are read as one test, the "
                             "hits renumbered in the order given, every file checked against the one --channels "
                             f"table (at most {MAX_HAMMER_FILES} files)")
    source.add_argument("--frf", action="append", type=existing_file("--frf", "FRF (UFF58)"),
                        help="UFF58 FRFs as an acquisition system exports them (function type 4, accelerance/"
                             "mobility/receptance, ASCII or binary, coherence optional), in place of --hammer; "
                             "one file")
    ident.add_argument("--channels", required=True, action="append",
                       type=existing_file("--channels", "channel table"),
                       help="channel table CSV of the setup (one table; several --hammer files share it)")
    ident.add_argument("--window-decay", type=bounded_float("--window-decay", 0.0, 1000.0, unit="1/s"),
                       default=None,
                       help="decay [1/s] of the exponential (response) window the front end applied to the --frf "
                            "file's FRFs, removed from the damping; default: the file's 'exp_window_decay=' note in "
                            "ID line 3, else none: the damping is then taken as exported (a WARNING says so), too "
                            "high by decay/omega if a window was applied. Only with --frf")
    ident.add_argument("--band", nargs=2, type=bounded_float("--band", 0.0, 1e5, unit="Hz"),
                       action=band_action("--band", 0.0, 1e5), default=[10.0, 500.0], metavar=("LOW", "HIGH"),
                       help="identification band [Hz], 0 <= LOW < HIGH <= fs/2 (default 10 500)")
    ident.add_argument("--max-order", type=bounded_int("--max-order", 1, MAX_ORDER), default=100,
                       help=f"largest LSCE order, 1 to {MAX_ORDER} (default 100)")
    ident.add_argument("--setup", default=None, help="setup name (default: the table's 'setup' column or file name)")
    ident.add_argument("--out", required=True, type=output_folder("--out"))
    ident.set_defaults(func=_cmd_identify, _identify_parser=ident)
    pair = lab_sub.add_parser("pair", help="pair identified modes with an FE export by MAC")
    pair.add_argument("--modes", required=True, action="append",
                      type=existing_folder("--modes", "modes (written by 'lab identify')"),
                      help="modes folder written by 'lab identify' (repeat for several setups: they are merged)")
    pair.add_argument("--fem", required=True, type=existing_file("--fem", "FE modes"),
                      help="FE modes file (UFF 2411/2412 with 55 or 2414, Nastran .pch, .f06 or .op2, an MSC "
                           "Nastran .h5, an ANSYS modal .rst or a CalculiX .frd)")
    add_geometry_argument(pair)
    pair.add_argument("--mac-min", type=bounded_float("--mac-min", 0.0, 1.0, lo_open=True), default=0.8,
                      help="smallest MAC of a pair, in (0, 1] (default 0.8)")
    pair.add_argument("--out", required=True, type=output_folder("--out"))
    pair.set_defaults(func=_cmd_pair)
    add_diagnose_parser(lab_sub)
    add_line_commands(lab_sub)
    add_model_commands(sub)
    add_field_commands(sub)
    add_monitor_commands(sub)
    add_field_diagnose_command(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _setup_logging(-1 if args.quiet else args.verbose - 1)
    try:
        return args.func(args)
    except (ValueError, KeyError, OSError, RuntimeError, ArithmeticError) as exc:
        print(f"railmodal: error: {exc}", file=sys.stderr)
        return 1
    except MemoryError:
        print("railmodal: error: out of memory; ask for a smaller problem (fewer lines, orders or models)",
              file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("railmodal: interrupted; nothing was written to --out (results are written last)", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001  the user gets one line, never a traceback (-v shows it)
        # the toolkit raises named errors (ValueError subclasses) for every input it checks; anything else is an
        # input it did not foresee or a fault of its own: say which operation failed, keep the detail for -v
        if args.verbose:
            import traceback

            traceback.print_exc()
        print(f"railmodal: error: unexpected {type(exc).__name__}: {exc}; an input the checks did not foresee or a "
              f"fault of the toolkit (run again with -v for the traceback, and report it)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
