"""A virtual-line measurement campaign: days × runs of the instrumented bogie, trolley days, the truth.

:func:`plan_line_campaign` decides everything cheap and random (dates, the
grinding, trolley days, every run's direction, ATO settings, odometer start
offset, wheel angles, faults) from the seed; :func:`build_world` makes the
heavy shared objects (rails over the whole line, wheels, the vehicle's modal
model, the track layout); :func:`simulate_run` turns one run into its MDF4
file and its truth; :func:`write_line_campaign` runs them in parallel on the
local cores and writes the campaign folder of the field contract.

Defaults (:class:`LineCampaignConfig`): 10 survey days spread evenly over
84 days from 2024-03-04, 7 runs a day alternating forward/backward from
06:00 every 95 minutes, the grinding night after day 6 (curves 1 and 2,
460–720 m and 990–1250 m, both rails), trolley days: the first day, the days
either side of the grinding and the last day. Runs with a dropout: every
run whose number in the campaign (from 0) is 1 mod 5 (a NaN segment and a
flat segment alternately); with a clipped channel: 2 mod 7. A ``section``
limits the simulation (and the files) to the time the bogie spends on that
stretch, with 12 m of travel simulated before it so the start transient
has died out; the runs are still the full station-to-station ATO runs, so a
section run sees the speed, odometer and balises a full run sees there.

Parallel runs use :class:`concurrent.futures.ProcessPoolExecutor` with the
``fork`` start method: the workers inherit the shared world (hundreds of MB
of roughness fields and the vehicle's modal model) without pickling it;
each worker's BLAS is held to one thread.
"""

from __future__ import annotations

import datetime as _dt
import logging
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd
from scipy import signal

from . import files
from .curving import CONTACT_ANGLE_TABLE, CurvingParameters
from .daq import DaqParameters, Fault, intervals, record_channels
from .geometry import Line, default_line, line_dict
from .odometry import OdometryParameters, simulate_odometry
from .operation import AtoParameters, TrainGeometry, ato_profile, draw_ato
from .passage import WHEELS, passage_arrays
from .roughness import (Grinding, RailRoughness, RoughnessConfig, WheelRoughness, build_rail_roughness,
                        build_wheel_roughness, contact_filter_kernel, hertz_semi_axis)
from .scenarios import FieldScenario, get_field_scenario
from .sensors import BALISE, POSITION, SPEED, AccelerometerSpec, draw_sensors, sensor_table

__all__ = ["LineConfigError", "LineCampaignConfig", "PlannedFault", "RunPlan", "LinePlan", "LineWorld", "plan_line_campaign",
           "build_world", "simulate_run", "write_line_campaign", "simulate_line", "GRINDING_SECTIONS",
           "TROLLEY_STRETCHES", "FIRST_CURVE_SECTION"]

log = logging.getLogger(__name__)

GRINDING_SECTIONS = ((460.0, 720.0), (990.0, 1250.0))
TROLLEY_STRETCHES = ((380.0, 820.0), (960.0, 1340.0))
#: A short stretch around curve 1: balise B02, the documented soft pads, the curve (corrugated low rail R), the
#: hidden trackform change of scenario ``trackform_change`` (720-780 m) and balise B03.
FIRST_CURVE_SECTION = (400.0, 800.0)
LEAD_IN_M = 12.0
LEAD_OUT_S = 0.1
CONTACT_LOSS_GAP_S = 5e-3  # losses closer than this are one event in the truth
MAX_DAYS, MAX_RUNS_PER_DAY = 30, 12
MIN_SECTION_M = 50.0
TROLLEY_NOISE_RMS_M = 0.3e-6
TROLLEY_HIGHPASS_M = 3.0
TRAIN = "Meneghino 805 (virtual)"
BOGIE = "car 2, trailer bogie"


class LineConfigError(ValueError):
    """Invalid campaign configuration: names the parameter, the allowed values and what was received."""


@dataclass(frozen=True)
class LineCampaignConfig:
    """Everything that defines a campaign (and its cache key)."""

    scenario: str = "nominal"
    days: int = 10
    runs_per_day: int = 7
    section: tuple[float, float] | None = None
    wheelset_scenario: str = "control"
    seed: int = 2022
    fs: float = 1000.0
    start_date: str = "2024-03-04"
    span_days: int = 84
    grinding_after_day: int | None = None  # 1-based; default: day round(0.6 days) when days >= 2
    trolley_days: tuple[int, ...] | None = None  # 1-based; default: first, either side of the grinding, last
    dt: float | None = None  # integration step; None: the dynamics core's default

    def __post_init__(self) -> None:
        get_field_scenario(self.scenario)
        from ..scenarios import SCENARIOS

        if self.wheelset_scenario not in SCENARIOS:
            raise LineConfigError(f"wheelset_scenario must be one of {sorted(SCENARIOS)}, got "
                                  f"{self.wheelset_scenario!r}")
        if not 1 <= self.days <= MAX_DAYS:
            raise LineConfigError(f"days must be in 1..{MAX_DAYS}, got {self.days}")
        if not 1 <= self.runs_per_day <= MAX_RUNS_PER_DAY:
            raise LineConfigError(f"runs_per_day must be in 1..{MAX_RUNS_PER_DAY}, got {self.runs_per_day}")
        if not 200.0 <= self.fs <= 5000.0:
            raise LineConfigError(f"fs must be in 200..5000 Hz, got {self.fs}")
        if self.span_days < self.days - 1 or self.span_days > 730:
            raise LineConfigError(f"span_days must be in {self.days - 1}..730 for {self.days} days, got "
                                  f"{self.span_days}")
        try:
            _dt.date.fromisoformat(self.start_date)
        except ValueError:
            raise LineConfigError(f"start_date must be an ISO date YYYY-MM-DD, got {self.start_date!r}") from None
        if self.section is not None:
            a, b = (float(v) for v in self.section)
            line = default_line()
            lo, hi = line.stations[0].chainage_m, line.stations[-1].chainage_m
            if not (lo <= a < b <= hi) or b - a < MIN_SECTION_M:
                raise LineConfigError(f"section must be FROM TO with {lo:g} <= FROM < TO <= {hi:g} m (the run "
                                      f"between the stations) and at least {MIN_SECTION_M:g} m long, got {self.section}")
            object.__setattr__(self, "section", (a, b))
        if self.grinding_after_day is not None and not 1 <= self.grinding_after_day < self.days:
            raise LineConfigError(f"grinding_after_day must be in 1..{self.days - 1}, got {self.grinding_after_day}")
        if self.trolley_days is not None:
            bad = [d for d in self.trolley_days if not 1 <= d <= self.days]
            if bad:
                raise LineConfigError(f"trolley_days must be in 1..{self.days}, got {bad}")
            object.__setattr__(self, "trolley_days", tuple(sorted(set(int(d) for d in self.trolley_days))))
        if self.dt is not None and not 1e-6 <= self.dt <= 1e-3:
            raise LineConfigError(f"dt must be in 1e-6..1e-3 s, got {self.dt}")

    def key_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class PlannedFault:
    """A fault decided at planning time: ``kind`` 'nan'/'flat' (dropout starting ``where`` (0-1) into the
    record, lasting ``duration_s``, at most a fifth of the record) or 'clip' (range set too tight)."""

    kind: str
    channel: str
    where: float = 0.0
    duration_s: float = 0.0


@dataclass(frozen=True)
class RunPlan:
    """One run: identity, operation and the faults it will carry."""

    run_id: str
    date: str
    day: int  # 1-based
    number: int  # 1-based within the day
    index: int  # 0-based within the campaign
    direction: str
    start_utc: str  # ISO time of the run's t = 0 (the train standing at the departure station)
    ato: AtoParameters
    start_offset_m: float
    wheelset_angle0: tuple[float, float]
    faults: tuple[PlannedFault, ...]


@dataclass(frozen=True)
class LinePlan:
    config: LineCampaignConfig
    line: Line
    scenario: FieldScenario
    dates: tuple[str, ...]
    grinding: Grinding | None
    trolley_dates: tuple[str, ...]
    trolley_offset_m: float
    runs: tuple[RunPlan, ...]
    roughness: RoughnessConfig
    wheel_radii: tuple[float, float, float, float]
    sensors: tuple[AccelerometerSpec, ...]
    curving: CurvingParameters
    odometry: OdometryParameters
    daq: DaqParameters
    train: TrainGeometry = field(default_factory=TrainGeometry)


def _dates(c: LineCampaignConfig) -> tuple[str, ...]:
    start = _dt.date.fromisoformat(c.start_date)
    offsets = np.round(np.linspace(0, c.span_days, c.days)).astype(int) if c.days > 1 else [0]
    return tuple((start + _dt.timedelta(days=int(o))).isoformat() for o in offsets)


def plan_line_campaign(config: LineCampaignConfig = LineCampaignConfig()) -> LinePlan:
    """Decide dates, grinding, trolley days and every run (cheap; deterministic for ``config.seed``)."""
    c = config
    line = default_line()
    scenario = get_field_scenario(c.scenario)
    dates = _dates(c)
    g_day = c.grinding_after_day if c.grinding_after_day is not None else (
        int(round(0.6 * c.days)) if c.days >= 2 else None)
    grinding = None
    if g_day is not None:
        d0, d1 = (_dt.date.fromisoformat(dates[g_day - 1]), _dt.date.fromisoformat(dates[g_day]))
        gdate = d0 + (d1 - d0) // 2 if (d1 - d0).days >= 2 else d1
        grinding = Grinding(gdate.isoformat(), GRINDING_SECTIONS)
    if c.trolley_days is not None:
        tdays = c.trolley_days
    else:
        tdays = {1, c.days} | ({g_day, g_day + 1} if g_day is not None else set())
    trolley_dates = tuple(dates[d - 1] for d in sorted(tdays))
    ss = np.random.SeedSequence(c.seed)
    s_line, s_wheels, s_runs, s_trolley = ss.spawn(4)
    rough = RoughnessConfig(seed=int(s_line.generate_state(1)[0]),
                            grindings=(grinding,) if grinding is not None else ())
    rng_w = np.random.default_rng(s_wheels)
    radii = []
    for _ in range(2):
        wear = rng_w.uniform(1.0e-3, 2.0e-3)
        radii += [0.41 - wear - d for d in (rng_w.uniform(-0.1e-3, 0.1e-3), rng_w.uniform(-0.1e-3, 0.1e-3))]
    sensors = draw_sensors(c.seed, scenario)
    runs = []
    run_seeds = s_runs.spawn(c.days * c.runs_per_day)
    for d, date in enumerate(dates):
        for k in range(c.runs_per_day):
            i = d * c.runs_per_day + k
            rng = np.random.default_rng(run_seeds[i])
            direction = "forward" if k % 2 == 0 else "backward"
            start = _dt.datetime.fromisoformat(date).replace(hour=5, tzinfo=_dt.timezone.utc) \
                + _dt.timedelta(minutes=95 * k + float(rng.uniform(0, 10)))
            ato = draw_ato(rng)
            faults = []
            if i % 5 == 1:
                faults.append(PlannedFault("nan" if (i // 5) % 2 == 0 else "flat",
                                           str(rng.choice([s.name for s in sensors])),
                                           where=float(rng.uniform(0.25, 0.6)),
                                           duration_s=float(rng.uniform(0.5, 1.5))))
            if i % 7 == 2:
                faults.append(PlannedFault("clip", str(rng.choice([s.name for s in sensors if s.direction == "z"]))))
            runs.append(RunPlan(
                run_id=f"{date.replace('-', '')}_{k + 1:02d}_{'fw' if direction == 'forward' else 'bw'}",
                date=date, day=d + 1, number=k + 1, index=i, direction=direction, start_utc=start.isoformat(),
                ato=ato, start_offset_m=float(rng.uniform(-2.5, 2.5)),
                wheelset_angle0=(float(rng.uniform(0, 2 * np.pi)), float(rng.uniform(0, 2 * np.pi))),
                faults=tuple(faults)))
    rng_t = np.random.default_rng(s_trolley)
    trolley_offset = float(rng_t.choice([-1.0, 1.0]) * rng_t.uniform(0.2, 0.6))
    return LinePlan(c, line, scenario, dates, grinding, trolley_dates, trolley_offset, tuple(runs), rough,
                    tuple(float(r) for r in radii), sensors,
                    CurvingParameters(gauge_narrowing_m=scenario.gauge_narrowing_m), OdometryParameters(),
                    DaqParameters(fs=c.fs))


# --------------------------------------------------------------------------------------------- the world


@dataclass(frozen=True)
class LineWorld:
    """The heavy shared objects of a campaign."""

    plan: LinePlan
    rails: RailRoughness
    wheels: WheelRoughness
    vehicle: object
    layout: object
    wheelbase: float
    wheel_load_n: float
    contact_semi_axis_m: float
    dt: float


def build_world(plan: LinePlan) -> LineWorld:
    """Rails over the whole line, wheels, the vehicle's modal model and the track layout (seconds)."""
    from .dynamics import DEFAULT_DT
    from .supports import track_layout
    from .vehicle import VehicleParameters, build_vehicle

    vp = VehicleParameters(wheelset_scenario=plan.config.wheelset_scenario)
    vehicle = build_vehicle(vp)
    layout = track_layout(plan.line, plan.scenario, plan.config.seed)
    rails = build_rail_roughness(plan.line, plan.roughness)
    wheels = build_wheel_roughness(np.array(plan.wheel_radii), plan.roughness.seed + 1,
                                   polygon=plan.scenario.wheel_polygon)
    load = float(np.mean(vehicle.static_load))
    a = hertz_semi_axis(load, vp.nominal_wheel_radius, vp.rail_crown_radius)
    return LineWorld(plan, rails, wheels, vehicle, layout, float(vp.wheelbase), load, a,
                     float(plan.config.dt or DEFAULT_DT))


_DAY_CACHE: dict = {}


def _filtered_rails(world: LineWorld, date: str) -> np.ndarray:
    """The day's rail roughness averaged over the contact length (per process, last day kept)."""
    if _DAY_CACHE.get("date") != date:
        from scipy.ndimage import convolve1d

        r = world.rails.on(date)
        k = contact_filter_kernel(world.contact_semi_axis_m, world.rails.config.dx)
        _DAY_CACHE.clear()
        _DAY_CACHE.update(date=date, rails=convolve1d(r, k, axis=1, mode="nearest"))
    return _DAY_CACHE["rails"]


def _window(plan: LinePlan, profile) -> tuple[float, float, float]:
    """(t_sim0, t_record_start, t_record_end) of a run in run time."""
    fs = plan.config.fs
    if plan.config.section is None:
        return 0.0, 0.0, profile.duration
    a, b = plan.config.section
    lo, hi = sorted((profile.s[0], profile.s[-1]))
    entry, exit_ = (a, b) if profile.travel_sign > 0 else (b, a)
    t_a = 0.0 if abs(entry - profile.s[0]) < 1e-9 else profile.time_at(entry)
    t_b = profile.duration if abs(exit_ - profile.s[-1]) < 1e-9 else profile.time_at(exit_)
    lead = entry - profile.travel_sign * LEAD_IN_M
    t_lead = profile.time_at(lead) if lo <= lead <= hi else 0.0
    m = int(np.floor((t_a - t_lead) * fs))
    return t_a - m / fs, t_a, t_b


def simulate_run(world: LineWorld, run: RunPlan, out_dir: Path) -> dict:
    """Simulate one run, write its MDF4 file and its truth Parquet; return its truth record."""
    from .dynamics import PassageInput, SensorPoint, simulate_passage

    plan = world.plan
    c = plan.config
    fs = c.fs
    profile = ato_profile(plan.line, run.direction, run.ato, plan.train)
    t_sim0, t_a, t_b = _window(plan, profile)
    t_end = min(t_b + LEAD_OUT_S, profile.duration)
    dt = world.dt
    t = t_sim0 + np.arange(int(np.floor((t_end - t_sim0) / dt)) + 1) * dt
    s, v, _ = profile.at(t)
    angle0 = np.repeat(np.array(run.wheelset_angle0), 2)
    arrays = passage_arrays(plan.line, t, s, v, run.direction, wheelbase=world.wheelbase,
                            rail=_filtered_rails(world, run.date), x0=float(world.rails.x[0]),
                            dx=world.rails.config.dx, wheels=world.wheels, wheel_angle0=angle0,
                            curving=plan.curving)
    sensors = tuple(SensorPoint(a.wheelset, a.side, a.direction, a.true) for a in plan.sensors)
    pin = PassageInput(dt=dt, bogie_chainage=s, travel_sign=profile.travel_sign, orientation="normal",
                       wheel_roughness=arrays.roughness, lateral_roughness=None, contact_angle=arrays.contact_angle,
                       curvature=arrays.curvature, cant=arrays.cant, sensors=sensors, speed=v)
    passage = simulate_passage(world.vehicle, world.layout, pin)

    # DAQ: AC-coupled ICP sensors, anti-aliasing + decimation, noise, range, faults
    m0 = int(round((t_a - t_sim0) * fs))
    n_rec = int(np.floor((t_b - t_a) * fs)) + 1
    rng = np.random.default_rng([c.seed, 1000 + run.index])
    faults = []  # in the DAQ's time (from the simulation start)
    for f in run.faults:
        if f.kind in ("nan", "flat"):
            faults.append(Fault(f.kind, f.channel, t_start_s=(t_a - t_sim0) + f.where * n_rec / fs,
                                duration_s=min(f.duration_s, 0.2 * n_rec / fs)))
        else:
            faults.append(Fault(f.kind, f.channel))
    channels = tuple(a.channel(plan.daq) for a in plan.sensors)
    acc = _ac_coupling(passage.acceleration, 1.0 / dt)
    rec, clip_mask, daq_info = record_channels(acc, 1.0 / dt, channels, tuple(faults), rng, plan.daq)
    rec, clip_mask = rec[:, m0:m0 + n_rec], clip_mask[:, m0:m0 + n_rec]
    if rec.shape[1] < n_rec:
        raise RuntimeError(f"run {run.run_id}: the simulation ended before the record window "
                           f"({rec.shape[1]} of {n_rec} samples)")
    t_rec = t_a + np.arange(n_rec) / fs
    s_rec, v_rec, _ = profile.at(t_rec)
    shift = t_a - t_sim0
    for i, (name, info) in enumerate(daq_info.items()):  # record times, with the bogie's chainage
        for d in info["dropouts"]:
            d["t_start_s"] -= shift
            d["t_end_s"] -= shift
            d["chainage_m"] = [float(np.interp(d[k], t_rec - t_a, s_rec)) for k in ("t_start_s", "t_end_s")]
        info["clipped_samples"] = int(clip_mask[i].sum())
        info["clipped"] = [{"t_s": [a / fs, b / fs], "chainage_m": [float(s_rec[a]), float(s_rec[b])]}
                           for a, b in intervals(clip_mask[i])]

    odo = simulate_odometry(plan.line, profile, plan.wheel_radii[2 * (plan.odometry.encoder_wheelset - 1)],
                            run.start_offset_m, plan.odometry)
    keep = (odo.t >= t_a - 1e-9) & (odo.t <= t_b + 1e-9)
    bkeep = (odo.balise_t >= t_a - 1e-9) & (odo.balise_t <= t_b + 1e-9)
    header = {"run_id": run.run_id, "date": run.date, "direction": run.direction, "orientation": "normal",
              "train": TRAIN, "bogie": BOGIE, "line": plan.line.id}
    start = _dt.datetime.fromisoformat(run.start_utc) + _dt.timedelta(seconds=t_a)
    mdf_path = out_dir / "runs" / run.date / f"{run.run_id}.mf4"
    files.write_run_mdf(
        mdf_path, start=start, header=header,
        description=f"virtual line {plan.line.id}, scenario {c.scenario}, run {run.run_id}",
        acc=rec, fs=fs, acc_names=[a.name for a in plan.sensors],
        acc_comments=[f"{'vertical' if a.direction == 'z' else 'lateral'} axlebox accelerometer, wheelset "
                      f"{a.wheelset} {a.side}; range +-{daq_info[a.name]['range_g']:g} g, {plan.daq.bits} bit"
                      for a in plan.sensors],
        odo_t=odo.t[keep] - t_a, speed=odo.speed[keep], position=odo.position[keep], odo_names=(SPEED, POSITION),
        balise_t=odo.balise_t[bkeep] - t_a, balise_value=odo.balise_value[bkeep], balise_name=BALISE)

    half = 0.5 * world.wheelbase
    pd.DataFrame({"t_s": t_rec - t_a, "chainage_m": s_rec, "speed_m_s": v_rec, "ws1_chainage_m": s_rec + half,
                  "ws2_chainage_m": s_rec - half}).to_parquet(out_dir / "truth" / "runs" / f"{run.run_id}.parquet",
                                                              index=False)
    lost = []
    cl = np.asarray(passage.contact_lost)
    gap = int(round(CONTACT_LOSS_GAP_S / dt))
    for w in range(4):
        for i0, i1 in intervals(cl[w], max_gap=gap):  # one event per bounce, however it flickers
            if t[i1] < t_a or t[i0] > t_b:
                continue
            lost.append({"wheel": WHEELS[w], "t_s": [float(t[i0] - t_a), float(t[i1] - t_a)],
                         "chainage_m": [float(arrays.wheel_chainage[w, i0]), float(arrays.wheel_chainage[w, i1])],
                         "steps_lost": int(cl[w, i0:i1 + 1].sum())})
    resets = [dict(r, t_s=r["t_s"] - t_a, t_pass_s=r["t_pass_s"] - t_a) for r in odo.resets
              if t_a - 1e-9 <= r["t_s"] <= t_b + 1e-9]
    return {
        "run_id": run.run_id, "date": run.date, "day": run.day, "number": run.number, "direction": run.direction,
        "leading_wheelset": arrays.leading_wheelset, "file": str(mdf_path.relative_to(out_dir)),
        "start_utc": start.isoformat(), "record_window_run_s": [t_a, t_b],
        "chainage_range_m": [float(s_rec[0]), float(s_rec[-1])], "samples": n_rec, "ato": run.ato.parameters(),
        "odometry": {"start_offset_m": run.start_offset_m, "scale": odo.scale, "resets": resets,
                     "position_error_at_start_m": float(odo.position[keep][0] - profile.at(np.array([t_a]))[0][0])},
        "wheelset_angle0_rad": list(run.wheelset_angle0),
        "planned_faults": [asdict(f) for f in run.faults],
        "daq": daq_info,
        "dropouts": [dict(d, channel=n) for n, i in daq_info.items() for d in i["dropouts"]],
        "clipped": [dict(x, channel=n, range_g=i["range_g"]) for n, i in daq_info.items() for x in i["clipped"]],
        "contact_loss": lost,
        "max_speed_m_s": float(v_rec.max()),
    }


def _ac_coupling(x: np.ndarray, fs: float, corner_hz: float = 0.5) -> np.ndarray:
    """The ICP accelerometer's AC coupling: first-order high-pass at ``corner_hz`` (causal)."""
    b, a = signal.butter(1, corner_hz, "highpass", fs=fs)
    return signal.lfilter(b, a, x, axis=-1)


# --------------------------------------------------------------------------------------------- the campaign


_WORLD: LineWorld | None = None
_OUT: Path | None = None


def _worker_run(run: RunPlan) -> tuple[dict, float]:
    """One run in a worker (BLAS on one thread); its truth record and the CPU seconds it took."""
    from threadpoolctl import threadpool_limits

    cpu0 = time.process_time()
    with threadpool_limits(1):
        record = simulate_run(_WORLD, run, _OUT)
    return record, time.process_time() - cpu0


def _stored_extent(plan: LinePlan, wheelbase: float) -> tuple[float, float]:
    if plan.config.section is None:
        return 0.0, plan.line.length_m
    a, b = plan.config.section
    m = LEAD_IN_M + wheelbase + 5.0
    return max(0.0, a - m), min(plan.line.length_m, b + m)


def _trolley(plan: LinePlan, rails: RailRoughness, date: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The trolley's record of ``date``: its chainage (own reference) and roughness (2, n) [m]."""
    stretches = TROLLEY_STRETCHES if plan.config.section is None else (plan.config.section,)
    truth = rails.on(date)
    dx = rails.config.dx
    b, a = signal.butter(2, dx / TROLLEY_HIGHPASS_M * 2, "highpass")
    xs, vals = [], []
    for lo, hi in stretches:
        c = np.arange(np.ceil(lo / dx), np.floor(hi / dx) + 1) * dx  # the trolley's own chainage, 1 mm steps
        true_x = c - plan.trolley_offset_m
        sl = rails.slice(true_x[0] - 10.0, true_x[-1] + 10.0)
        rows = np.stack([np.interp(true_x, rails.x[sl], truth[r, sl]) for r in range(2)])
        rows = signal.filtfilt(b, a, rows, axis=1) + TROLLEY_NOISE_RMS_M * rng.standard_normal(rows.shape)
        xs.append(c)
        vals.append(rows)
    return np.concatenate(xs), np.concatenate(vals, axis=1)


def write_line_campaign(plan: LinePlan, out_dir: str | Path, *, progress: Callable[[str], None] | None = None,
                        workers: int | None = None) -> dict[str, Path]:
    """Simulate every run (in parallel) and write the campaign folder; returns the main files by key."""
    global _WORLD, _OUT
    say = progress or (lambda msg: log.info("%s", msg))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "truth" / "runs").mkdir(parents=True, exist_ok=True)
    c = plan.config
    say(f"building the line, rails, wheels and the vehicle (wheelset scenario {c.wheelset_scenario!r})")
    world = build_world(plan)
    out_files = {"line": files.write_json(line_dict(plan.line), out / "line.json")}
    sensor_table(plan.sensors).to_csv(out / "sensors.csv", index=False)
    out_files["sensors"] = out / "sensors.csv"

    workers = max(1, min(workers or os.cpu_count() or 1, len(plan.runs)))
    say(f"simulating {len(plan.runs)} runs ({c.days} day(s) x {c.runs_per_day}) on {workers} worker(s)")
    records = {}
    _WORLD, _OUT = world, out
    try:
        if workers == 1:
            for k, run in enumerate(plan.runs):
                records[run.run_id], cpu = _worker_run(run)
                say(f"run {k + 1}/{len(plan.runs)} {run.run_id} written (cpu {cpu:.1f} s)")
        else:
            ctx = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
                futures = {pool.submit(_worker_run, run): run for run in plan.runs}
                for k, fut in enumerate(as_completed(futures)):
                    run = futures[fut]
                    records[run.run_id], cpu = fut.result()
                    say(f"run {k + 1}/{len(plan.runs)} {run.run_id} written (cpu {cpu:.1f} s)")
    finally:
        _WORLD, _OUT = None, None

    say("writing the trolley files and the truth")
    rng_t = np.random.default_rng([c.seed, 77])
    for date in plan.trolley_dates:
        x, r = _trolley(plan, world.rails, date, rng_t)
        out_files[f"trolley_{date}"] = files.write_trolley_csv(out / "trolley" / f"{date}.csv", x, r)
    lo, hi = _stored_extent(plan, world.wheelbase)
    sl = world.rails.slice(lo, hi)
    for date in plan.dates:
        files.write_roughness_parquet(out / "truth" / "rail_roughness" / f"{date}.parquet", world.rails.x[sl],
                                      world.rails.on(date)[:, sl])
    m = world.wheels.table.shape[1]
    pd.DataFrame({"angle_rad": 2 * np.pi * np.arange(m) / m,
                  **{f"{w}_um": (world.wheels.table[i] * 1e6).astype(np.float32) for i, w in enumerate(WHEELS)}}
                 ).to_parquet(out / "truth" / "wheel_roughness.parquet", index=False)
    sup = {"chainage_m": world.layout.support_chainage}
    for name, arr in world.layout.support_factors.items():
        for r, rail in enumerate("LR"):
            sup[f"{name}_{rail}"] = arr[r]
    pd.DataFrame(sup).to_parquet(out / "truth" / "supports.parquet", index=False)
    manifest = _manifest(plan, world, [records[r.run_id] for r in plan.runs], (lo, hi))
    out_files["truth"] = files.write_json(manifest, out / "truth" / "truth.json")
    say(f"campaign {c.scenario!r} complete: {len(plan.runs)} runs")
    return out_files


def _manifest(plan: LinePlan, world: LineWorld, runs: list[dict], extent: tuple[float, float]) -> dict:
    c = plan.config
    days = []
    for d, date in enumerate(plan.dates):
        patches = []
        for p in plan.roughness.patches:
            epoch, age = world.rails.patch_state(p, date)
            patches.append({"id": p.id, "rail": p.rail, "from_m": p.from_m, "to_m": p.to_m, "epoch": epoch,
                            "days_since_grinding": age, "wavelengths_m": list(p.wavelengths_m),
                            "pk_pk_um": list(p.pk_pk_um(age))})
        days.append({"day": d + 1, "date": date, "trolley": date in plan.trolley_dates, "corrugation": patches,
                     "runs": [r["run_id"] for r in runs if r["date"] == date]})
    enc = plan.odometry.encoder_wheelset
    return {
        "format": files.TRUTH_FORMAT, "version": files.TRUTH_VERSION,
        "config": c.key_dict(),
        "scenario": plan.scenario.parameters(),
        "wheelset_scenario": c.wheelset_scenario,
        "line": {"id": plan.line.id, "file": "line.json", "stored_extent_m": list(extent)},
        "days": days,
        "grinding": None if plan.grinding is None else {
            "date": plan.grinding.date, "sections_m": [list(x) for x in plan.grinding.sections],
            "last_day_before": max(d for d in plan.dates if d < plan.grinding.date),
            "first_day_after": min(d for d in plan.dates if d >= plan.grinding.date)},
        "roughness": {
            "model": "see lab_data/line/roughness.py",
            "config": plan.roughness.parameters(),
            "corrugation_growth": "pk_pk_um = residual_pk_pk_um + rate_um_per_day * days_since_grinding "
                                  "(pk-pk = 2 sqrt(2) x RMS of each component over the patch body)",
            "welds_and_switches": list(world.rails.welds),
            "files": "truth/rail_roughness/<date>.parquet: chainage_m, L_um, R_um (unfiltered, what a perfect "
                     "trolley measures)",
            "contact_filter": {"semi_axis_m": world.contact_semi_axis_m, "wheel_load_N": world.wheel_load_n,
                               "weights": "sqrt(1 - (x/a)^2), unit sum, applied to rail roughness seen by "
                                          "the wheels"},
        },
        "wheels": {"order": list(WHEELS), "nominal_radius_m": plan.odometry.nominal_radius_m,
                   "true_radius_m": list(plan.wheel_radii), "polygon": plan.scenario.wheel_polygon,
                   "level_offset_db": world.wheels.level_offset_db,
                   "file": "truth/wheel_roughness.parquet"},
        "vehicle": {"wheelbase_m": world.wheelbase, "static_wheel_load_N": world.wheel_load_n,
                    "orientation": "normal", "dt_s": world.dt},
        "sensors": [{"name": a.name, "wheelset": a.wheelset, "side": a.side, "direction": a.direction,
                     "nominal_m": list(a.nominal), "true_m": list(a.true),
                     "offset_m": [t - n for t, n in zip(a.true, a.nominal)],
                     "sensitivity_error": a.sensitivity_error, "sign": a.sign} for a in plan.sensors],
        "daq": {**plan.daq.parameters(), "unit": "g", "ac_coupling_hz": 0.5,
                "anti_alias": "linear-phase Kaiser FIR (100 dB), passband 0.4 fs, stopband 0.5 fs, delay compensated"},
        "curving": {**plan.curving.parameters(), "contact_angle_table_mm_deg": [list(p) for p in CONTACT_ANGLE_TABLE],
                    "sign": "thesis eq. 2.12: theta_L = -gamma_L, theta_R = +gamma_R"},
        "odometry": {**asdict(plan.odometry), "encoder_true_radius_m": plan.wheel_radii[2 * (enc - 1)],
                     "scale": plan.odometry.nominal_radius_m / plan.wheel_radii[2 * (enc - 1)]},
        "supports": {"file": "truth/supports.parquet", "hidden_changes": [dict(x) for x in plan.scenario.support_changes]},
        "trolley": {"dates": list(plan.trolley_dates), "offset_m": plan.trolley_offset_m,
                    "offset_meaning": "trolley chainage = true chainage + offset_m",
                    "noise_rms_m": TROLLEY_NOISE_RMS_M, "highpass_wavelength_m": TROLLEY_HIGHPASS_M,
                    "stretches_m": [list(s) for s in (TROLLEY_STRETCHES if c.section is None else (c.section,))]},
        "runs": runs,
    }


def simulate_line(scenario: str, out_dir: str | Path, *, progress: Callable[[str], None] | None = None,
                  workers: int | None = None, **config) -> dict[str, Path]:
    """Plan and write a campaign of ``scenario`` into ``out_dir`` (see :class:`LineCampaignConfig`)."""
    plan = plan_line_campaign(LineCampaignConfig(scenario=scenario, **config))
    return write_line_campaign(plan, out_dir, progress=progress, workers=workers)
