"""A virtual impact-test campaign: plan it from the truth, then write the files a lab writes.

:func:`plan_campaign` solves the design and as-built models of a scenario,
places the sensors of both setups, draws the hits (seeded) and decides the
channel ranges; :func:`write_campaign` synthesises every hit and writes

* ``fe_design.uff`` — design FE export: UFF 164 + 2411 + 2412 + 55 (6 DOF per
  node, mass-normalised, rigid-body modes included, degenerate pairs in the
  arbitrary basis an FE solver returns), in the style ``fe_style`` asks for
  (:mod:`lab_data.fe_styles`: the lab's 3D ``mesh`` or a design office's
  ``beam``-and-lumped-mass model); the hammer data are the same in both;
* ``fe_design.pch`` — the same modes as a Nastran punch file;
* ``<setup>.uff`` — binary UFF58 time histories (function type 1), one dataset
  per channel per hit, hit number in the sequence-number field;
* ``<setup>_channels.csv`` — the channel table (``fe_node`` on the exported model);
* ``points.csv`` — contact points and axlebox centres with their FE nodes;
* ``truth.json`` — the truth manifest (only tests read it).

The hits per setup (default 6): amplitudes 0.8–1.2 kN, half-sine widths
0.35–0.9 ms (hammer tip), 0.1 s pre-trigger, 4 s records at 12.8 kHz. Hit 3
is a double hit (the hammer bounces back 3–6 ms later at 30–50 %); hit 5 is
struck hard enough to overload the accelerometer with the strongest
response, whose range the engineer had set tighter than the others. Channel ranges follow
an auto-range from the nominal hits (four times the largest peak, rounded up
to the 1-2-5 series), except the overloaded channel's custom range of 1.05
times its largest nominal peak; the ADC has 24 bits; accelerometers add 5e-3 m/s² RMS
noise (a 100 mV/g ICP sensor and front end), the force sensor 0.05 N RMS.
Every hit strikes along the setup's hammer direction, unless ``hammer_scatter_deg`` tilts each blow at random
(a hand-held hammer's scatter; the tilts are in the manifest's hits).
"""

from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from .fe_styles import FE_STYLES, DesignExport, beam_export, mesh_export, sensor_mac
from .hammer import ModalTruth, Pulse, add_noise, quantise, synthesize_hit
from .nastran_punch import write_punch_eigenvectors
from .scenarios import Scenario, get_scenario
from .sensors import (SETUP_NAMES, Setup, channel_table, make_setup, point_rows, points_frame, shape_matrix,
                      tilted_direction)
from .truth import BAND_HZ, SetupView, SolvedModel, check_spectral_gap, design_modes, setup_view, truncated, truth_modes
from .uff_export import TimeHistory, write_fe_uff, write_time_histories
from .wheelset import WheelsetParameters

__all__ = ["CampaignConfig", "HitPlan", "CampaignPlan", "plan_campaign", "write_campaign", "simulate"]

log = logging.getLogger(__name__)

OBSERVABLE_PEAK_RATIO = 0.02
ACC_NOISE_RMS = 5e-3
FORCE_NOISE_RMS = 0.05
FORCE_RANGE = 10000.0  # a large impact hammer for a 1.2 t wheelset (about 22 kN span)
MANIFEST_FORMAT = "railmodal-virtual-lab-truth"
MANIFEST_VERSION = 1


@dataclass(frozen=True)
class CampaignConfig:
    """Everything that defines a campaign (and its cache key)."""

    scenario: str = "control"
    fe_max_hz: float = 500.0
    #: Highest mode of the design FE export (default: ``fe_max_hz``). Structural modifications (bearings,
    #: joints) need modes beyond the test band as their basis, so an FE analyst exports to a few times the
    #: band; the truth is still synthesised below ``fe_max_hz``.
    fe_export_hz: float | None = None
    fs: float = 12800.0
    duration: float = 4.0
    pretrigger: float = 0.1
    n_hits: int = 6
    double_hit: int = 3
    overload_hit: int = 5
    seed: int = 1863
    oversample: int = 4
    #: Style of the design FE export (:data:`lab_data.fe_styles.FE_STYLES`): ``mesh`` (the lab's 3D model) or
    #: ``beam`` (a design office's rotor-dynamics model: beam axle, lumped masses, rims on web springs).
    fe_style: str = "mesh"
    #: RMS tilt [deg] of each hit's blow about the setup's hammer direction, drawn per hit towards the axle and
    #: about it (a hand-held hammer's scatter); 0: every hit along the same direction.
    hammer_scatter_deg: float = 0.0

    def __post_init__(self) -> None:
        get_scenario(self.scenario)
        if self.fe_style not in FE_STYLES:
            raise ValueError(f"fe_style must be one of {list(FE_STYLES)}, got {self.fe_style!r}")
        if self.n_hits < 5:
            raise ValueError(f"n_hits must be >= 5, got {self.n_hits}")
        for name in ("double_hit", "overload_hit"):
            h = getattr(self, name)
            if not 1 <= h <= self.n_hits:
                raise ValueError(f"{name} must be a hit number in 1..{self.n_hits}, got {h}")
        if self.double_hit == self.overload_hit:
            raise ValueError("double_hit and overload_hit must be different hits")
        if self.duration < 4.0:
            raise ValueError(f"duration must be >= 4 s (thesis records), got {self.duration}")
        if self.fe_max_hz <= BAND_HZ[1] * 0.5:
            raise ValueError(f"fe_max_hz must cover the analysis band, got {self.fe_max_hz}")
        if self.fe_export_hz is not None and self.fe_export_hz < self.fe_max_hz:
            raise ValueError(f"fe_export_hz ({self.fe_export_hz}) must be >= fe_max_hz ({self.fe_max_hz})")
        if not 0.0 <= self.hammer_scatter_deg <= 20.0:
            raise ValueError(f"hammer_scatter_deg must be within 0-20 degrees, got {self.hammer_scatter_deg}")

    @property
    def export_hz(self) -> float:
        """Highest frequency of the design FE export."""
        return self.fe_max_hz if self.fe_export_hz is None else self.fe_export_hz


@dataclass(frozen=True)
class HitPlan:
    hit: int
    pulses: tuple[Pulse, ...]
    double: bool
    overload: bool
    #: the blow's tilt [deg] from the setup's hammer direction, towards the axle and about it
    tilt_deg: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class CampaignPlan:
    """The truth and the test plan of a campaign, before any signal is synthesised.

    ``design`` is the lab's 3D design model (it names the truth's modes and
    carries the transducers the hits are synthesised at); ``export`` is the
    design FE as written in the campaign's ``fe_style``, whose modes are
    ``export_freqs_hz``/``export_shapes`` and which ``pairs`` (truth mode ->
    exported partner modes, MAC) refer to.
    """

    config: CampaignConfig
    scenario: Scenario
    params: WheelsetParameters
    design: SolvedModel
    export_freqs_hz: np.ndarray
    export_shapes: np.ndarray
    truth: SolvedModel
    setups: dict[str, Setup]
    views: dict[str, SetupView]
    modal: dict[str, ModalTruth]
    hits: dict[str, tuple[HitPlan, ...]]
    pairs: list
    points: list = field(default_factory=list)
    export: DesignExport | None = None


def _draw_hits(config: CampaignConfig, rng: np.random.Generator) -> tuple[HitPlan, ...]:
    hits = []
    for h in range(1, config.n_hits + 1):
        width = rng.uniform(0.35e-3, 0.9e-3)
        amp = rng.uniform(800.0, 1200.0)
        t0 = config.pretrigger + rng.uniform(0.0, 2e-3)
        pulses = [Pulse(t0, width, amp)]
        if h == config.double_hit:
            pulses.append(Pulse(t0 + width + rng.uniform(3e-3, 6e-3), width, amp * rng.uniform(0.3, 0.5)))
        hits.append(HitPlan(h, tuple(pulses), h == config.double_hit, h == config.overload_hit))
    return tuple(hits)


def plan_campaign(config: CampaignConfig = CampaignConfig(), params: WheelsetParameters = WheelsetParameters()) -> CampaignPlan:
    """Solve the design and truth models of a scenario and plan both setups' hits.

    Raises
    ------
    ValueError
        If the export frequency falls next to a mode (see
        :func:`lab_data.truth.check_spectral_gap`).
    """
    scenario = get_scenario(config.scenario)
    log.info("solving the design FE model up to %.0f Hz", config.export_hz)
    design_all = design_modes(params, config.export_hz * 1.1)
    check_spectral_gap(design_all.modes.freqs_hz, config.export_hz, "design FE export")
    keep = design_all.modes.freqs_hz <= config.export_hz
    design = truncated(design_all, keep)

    f_truth = scenario.truth_max_hz or config.fe_max_hz
    log.info("solving the as-built truth (%s) up to %.0f Hz", scenario.name, f_truth)
    truth_all = truth_modes(scenario, params, f_truth * 1.1, design)
    if scenario.truth_max_hz is None:
        check_spectral_gap(truth_all.modes.freqs_hz, f_truth, f"truth of scenario {scenario.name!r}")
    truth = truncated(truth_all, truth_all.modes.freqs_hz <= f_truth)

    points = point_rows(design.model, params)
    setups = {name: make_setup(name, design.model, params) for name in SETUP_NAMES}
    if config.fe_style == "mesh":
        export = mesh_export(design, truth, setups, points, np.random.default_rng(config.seed))
    else:
        log.info("solving the beam design FE model up to %.0f Hz", config.export_hz)
        export = beam_export(params, config.export_hz, design, truth, setups, points,
                             np.random.default_rng([config.seed, 2]))
    views, modal, hits = {}, {}, {}
    for name in SETUP_NAMES:
        view = setup_view(truth, setups[name], points)
        views[name] = view
        modal[name] = ModalTruth(view.freqs_hz, view.zeta, view.input_shape, view.output_shapes)
        hits[name] = _draw_hits(config, np.random.default_rng([config.seed, SETUP_NAMES.index(name)]))
        if config.hammer_scatter_deg > 0:
            # a stream of its own: the hits of a campaign without scatter stay as they were
            tilt = np.random.default_rng([config.seed, 300 + SETUP_NAMES.index(name)]).normal(
                0.0, config.hammer_scatter_deg, (len(hits[name]), 2))
            hits[name] = tuple(replace(h, tilt_deg=(float(a), float(b))) for h, (a, b) in zip(hits[name], tilt))
    return CampaignPlan(
        config, scenario, params, design, export.freqs_hz, export.shapes, truth, setups, views, modal, hits,
        export.pairs, points, export,
    )


def _nice_ceil(x: np.ndarray) -> np.ndarray:
    """Round up to the 1-2-5 series (an input-range list of a front end)."""
    x = np.asarray(x, float)
    decade = 10.0 ** np.floor(np.log10(x))
    out = np.full_like(x, np.inf)
    for m in (1.0, 2.0, 5.0, 10.0):
        cand = m * decade
        out = np.where((cand >= x * (1 - 1e-12)) & (cand < out), cand, out)
    return out


def _direction_code(d: tuple[float, float, float]) -> int:
    d = np.asarray(d)
    k = int(np.argmax(np.abs(d)))
    if abs(abs(d[k]) - 1.0) < 1e-9:
        return int(np.sign(d[k])) * (k + 1)
    return 0


def hit_truth(plan: CampaignPlan, setup_name: str, hit: HitPlan) -> ModalTruth:
    """The modal model one hit excites: the setup's, with the participations at the hit's tilted blow (in the
    setup's basis of degenerate modes, so that every hit's responses share its output shapes)."""
    modal = plan.modal[setup_name]
    if hit.tilt_deg == (0.0, 0.0):
        return modal
    force = plan.setups[setup_name].force
    b = shape_matrix(plan.truth.model, plan.views[setup_name].shapes_full, [force.fe_node], [force.position],
                     [tilted_direction(force.direction, *hit.tilt_deg)])[0]
    return ModalTruth(modal.freqs_hz, modal.zeta, b, modal.output_shapes)


def _synthesise(plan: CampaignPlan, setup_name: str, hit: HitPlan) -> tuple[np.ndarray, np.ndarray]:
    c = plan.config
    _, force, acc = synthesize_hit(hit_truth(plan, setup_name, hit), hit.pulses, fs=c.fs, duration=c.duration,
                                   oversample=c.oversample)
    return force, acc


def _ranges_and_overload(plan: CampaignPlan, setup_name: str, clean: dict[int, tuple]) -> tuple[np.ndarray, int, float]:
    """Channel ranges from the nominal hits, the overloaded channel and the overload hit's amplitude factor."""
    nominal = [h for h in plan.hits[setup_name] if not h.overload]
    peaks = np.max([np.max(np.abs(clean[h.hit][1]), axis=1) for h in nominal], axis=0)
    ranges = _nice_ceil(4.0 * peaks)
    hot = int(np.argmax(peaks))
    # the engineer typed a tight custom range for the most responsive channel
    ranges[hot] = float(np.format_float_positional(1.05 * peaks[hot], precision=3, unique=False, fractional=False))
    over = next(h for h in plan.hits[setup_name] if h.overload)
    unit_peak = np.max(np.abs(clean[over.hit][1]), axis=1)
    factor = 1.3 * ranges[hot] / unit_peak[hot]  # scales the drawn amplitude so the hot channel overloads by 30 %
    others = np.delete(factor * unit_peak / ranges, hot)
    if np.any(others >= 0.9) or factor * np.max(np.abs(clean[over.hit][0])) >= 0.9 * FORCE_RANGE:
        raise RuntimeError(
            f"setup {setup_name}: the overload hit would clip more than one channel "
            f"(worst other channel at {others.max():.2f} of its range)"
        )
    return ranges, hot, factor


def write_campaign(
    plan: CampaignPlan, out_dir: str | Path, *, progress: Callable[[str], None] | None = None
) -> dict[str, Path]:
    """Synthesise every hit and write the campaign's files into ``out_dir``.

    Returns
    -------
    dict of str to Path
        ``fe_uff``, ``fe_punch``, ``points``, ``truth``, and per setup
        ``<setup>_uff`` and ``<setup>_channels``.
    """
    say = progress or (lambda msg: log.info("%s", msg))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    c = plan.config
    files: dict[str, Path] = {}
    export = plan.export
    model = export.solved.model

    say(f"writing the design FE export ({export.style} style, {len(plan.export_freqs_hz)} modes up to "
        f"{c.export_hz:g} Hz)")
    files["fe_uff"] = write_fe_uff(
        out / "fe_design.uff",
        model.node_ids,
        model.xyz,
        list(export.elements),
        plan.export_freqs_hz,
        plan.export_shapes,
        model_name=export.model_name,
        description=export.description,
    )
    files["fe_punch"] = write_punch_eigenvectors(
        out / "fe_design.pch", model.node_ids, plan.export_freqs_hz, plan.export_shapes, title=export.punch_title,
    )
    points_frame(export.points).to_csv(out / "points.csv", index=False)
    files["points"] = out / "points.csv"

    manifest_setups = {}
    for name in SETUP_NAMES:
        setup = plan.setups[name]
        hits = plan.hits[name]
        say(f"setup {name}: synthesising {len(hits)} hits ({len(setup.accelerometers)} accelerometers + force)")
        clean = {h.hit: _synthesise(plan, name, h) for h in hits}
        ranges, hot, factor = _ranges_and_overload(plan, name, clean)
        rng = np.random.default_rng([c.seed, 100 + SETUP_NAMES.index(name)])
        histories = []
        hit_records = []
        for h in hits:
            force, acc = clean[h.hit]
            pulses = h.pulses
            if h.overload:
                force, acc = force * factor, acc * factor
                pulses = tuple(Pulse(p.t0, p.width, p.amplitude * factor) for p in pulses)
            force = add_noise(force, FORCE_NOISE_RMS, rng)
            acc = add_noise(acc, ACC_NOISE_RMS, rng)
            force_q, force_clip = quantise(force, FORCE_RANGE)
            acc_q, acc_clip = quantise(acc, ranges)
            clipped = [setup.accelerometers[j].node for j in np.flatnonzero(acc_clip.any(axis=1))]
            if force_clip.any():
                raise RuntimeError(f"setup {name} hit {h.hit}: the force channel clipped")
            if (h.overload and clipped != [setup.accelerometers[hot].node]) or (not h.overload and clipped):
                raise RuntimeError(f"setup {name} hit {h.hit}: unexpected clipped channels {clipped}")
            dt = 1.0 / c.fs
            f_dir = _direction_code(setup.force.direction)
            histories.append(TimeHistory(h.hit, setup.force.node, f_dir, "force", "N", setup.force.name, dt, force_q,
                                         setup.force.node, f_dir))
            for j, s in enumerate(setup.accelerometers):
                histories.append(TimeHistory(h.hit, s.node, _direction_code(s.direction), "acceleration", "m/s^2",
                                             s.name, dt, acc_q[j], setup.force.node, f_dir))
            hit_records.append(
                {
                    "hit": h.hit,
                    "pulses": [asdict(p) for p in pulses],
                    "double": h.double,
                    "overload": h.overload,
                    "clipped_nodes": clipped,
                    "clipped_samples": int(acc_clip.sum()),
                    "tilt_deg": list(h.tilt_deg),
                }
            )
        say(f"setup {name}: writing {len(histories)} UFF58 datasets")
        files[f"{name}_uff"] = write_time_histories(out / f"{name}.uff", histories, binary=True)
        table = channel_table(export.setups[name])
        table.to_csv(out / f"{name}_channels.csv", index=False)
        files[f"{name}_channels"] = out / f"{name}_channels.csv"
        manifest_setups[name] = _setup_manifest(plan, name, ranges, hit_records)

    manifest = {
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "config": asdict(c),
        "scenario": plan.scenario.parameters(),
        "band_hz": list(BAND_HZ),
        "observable_peak_ratio": OBSERVABLE_PEAK_RATIO,
        "noise_rms": {"acceleration_m_per_s2": ACC_NOISE_RMS, "force_N": FORCE_NOISE_RMS},
        "adc_bits": 24,
        "force_range_N": FORCE_RANGE,
        "fe_style": export.style,
        "design_modes": [
            {"mode": i + 1, "f_hz": float(f), "description": lab.description, "family": lab.family}
            for i, (f, lab) in enumerate(zip(plan.export_freqs_hz, export.solved.labels))
        ],
        "files": {k: v.name for k, v in files.items()},
        "setups": manifest_setups,
    }
    if export.beam is not None:
        manifest["beam_model"] = _beam_manifest(export)
    (out / "truth.json").write_text(json.dumps(manifest, indent=1))
    files["truth"] = out / "truth.json"
    say(f"campaign {plan.scenario.name!r} written to {out}")
    return files


def _beam_manifest(export: DesignExport) -> dict:
    """What the beam design assumed (for tests and the closing note; a real export would not say it)."""
    b = export.beam
    return {
        "axle_nodes": b.axle_nodes.tolist(),
        "axle_y_m": b.axle_y.tolist(),
        "seat_node": b.seat_node,
        "disc_node": b.disc_node,
        "journal_node": b.journal_node,
        "rim_node": b.rim_node,
        "web_springs": {"axial_N_per_m": b.web.axial, "radial_N_per_m": b.web.radial,
                        "rocking_Nm_per_rad": b.web.rocking, "torsional_Nm_per_rad": b.web.torsional},
        "rim_body": {"mass_kg": b.rim.mass, "diametral_kg_m2": b.rim.diametral, "polar_kg_m2": b.rim.polar},
        "hub": {"mass_kg": b.hub[0], "diametral_kg_m2": b.hub[1], "polar_kg_m2": b.hub[2]},
        "disc": {"mass_kg": b.disc[0], "diametral_kg_m2": b.disc[1], "polar_kg_m2": b.disc[2]},
        "axlebox": "lumped on the journal node",
    }


def _setup_manifest(plan: CampaignPlan, name: str, ranges: np.ndarray, hit_records: list) -> dict:
    setup = plan.export.setups[name]
    view = plan.views[name]
    modes = []
    for i, f in enumerate(view.freqs_hz):
        lab = view.labels[i]
        partner, mac = plan.pairs[i]
        in_band = BAND_HZ[0] <= f <= BAND_HZ[1]
        modes.append(
            {
                "id": i,
                "f_hz": float(f),
                "zeta": float(view.zeta[i]),
                "description": lab.description,
                "family": lab.family,
                "order": lab.order,
                "plane": lab.plane,
                "nodal_diameters": lab.nodal_diameters,
                "fe_partner": [k + 1 for k in partner],
                "fe_mac": mac,
                "fe_mac_sensors": sensor_mac(plan.export, name, view.output_shapes[:, i], partner),
                "peak_ratio": float(view.peak_ratio[i]),
                "observable": bool(in_band and view.peak_ratio[i] >= OBSERVABLE_PEAK_RATIO),
                "input_shape": float(view.input_shape[i]),
                "shapes": view.output_shapes[:, i].tolist(),
                "points": {
                    pname: view.point_shapes[3 * k : 3 * k + 3, i].tolist() for k, (pname, _, _) in enumerate(plan.points)
                },
            }
        )
    return {
        "uff": f"{name}.uff",
        "channels": f"{name}_channels.csv",
        "force": {"node": setup.force.node, "fe_node": setup.force.fe_node, "position": setup.force.position,
                  "direction": setup.force.direction},
        "accelerometer_nodes": [s.node for s in setup.accelerometers],
        "ranges_m_per_s2": {str(s.node): float(r) for s, r in zip(setup.accelerometers, ranges)},
        "hits": hit_records,
        "double_hits": [h["hit"] for h in hit_records if h["double"]],
        "clipped": [{"hit": h["hit"], "node": n} for h in hit_records for n in h["clipped_nodes"]],
        "modes": modes,
    }


def simulate(scenario: str, out_dir: str | Path, *, progress: Callable[[str], None] | None = None,
             design: str = "default", **config) -> dict[str, Path]:
    """Plan and write a campaign of ``scenario`` on the wheelset ``design`` (:data:`lab_data.designs.DESIGNS`) into
    ``out_dir`` (see :class:`CampaignConfig` for options)."""
    from .designs import get_design

    plan = plan_campaign(CampaignConfig(scenario=scenario, **config), get_design(design))
    return write_campaign(plan, out_dir, progress=progress)
