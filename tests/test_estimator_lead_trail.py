"""The two wheelsets' estimates of the same rails: the wheelset's lag, and the channels checked against the
sensor table.

Oracles: rails of known roughness seen by two wheelsets a known wheelbase apart, with each way a sensor table can
contradict the accelerometers applied to the estimates (sign, vehicle side, wheelset number, direction); and the
end-to-end estimate of a synthetic run with one accelerometer mounted upside down.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from estimator.lead_trail import MIN_CORRELATION, arrangement_findings, lead_trail

DX = 0.005
RANGE = (1.2, 4.0)
NAMES = {(w, r): f"ACC_W{w}{r}_Z" for w in (1, 2) for r in "LR"}


def _rails(seed: int, length_m: float = 150.0) -> dict[str, np.ndarray]:
    """Two independent broadband rails on a 5 mm grid (white in 0.05–1.2 m, where the correlation looks)."""
    rng = np.random.default_rng(seed)
    n = int(length_m / DX)
    return {r: rng.standard_normal(n) for r in "LR"}


def _seen(rails: dict[str, np.ndarray], wheelbase: float, lead_sign: int = 1, own: float = 0.5, seed: int = 1
          ) -> dict[tuple[int, str], np.ndarray]:
    """Each wheelset's estimate of each rail at the bogie's centre's grid: wheelset 1 at ``x + s a/2``, wheelset 2 at
    ``x − s a/2``, plus its own (uncorrelated) error of relative RMS ``own``; NaN off the rails' ends."""
    rng = np.random.default_rng(seed)
    shift = int(round(wheelbase / 2 / DX))
    out = {}
    for w, sgn in ((1, lead_sign), (2, -lead_sign)):
        for r, y in rails.items():
            e = np.full(y.size, np.nan)
            if sgn > 0:
                e[:y.size - shift] = y[shift:]
            else:
                e[shift:] = y[:y.size - shift]
            out[(w, r)] = e + own * rng.standard_normal(y.size)
    return out


def _check(profiles, lead_sign=1):
    lt = lead_trail(profiles, DX, 0.05, lead_sign, RANGE)
    return lt, arrangement_findings(lt, NAMES, direction="forward", orientation="normal")


def test_consistent_estimates_measure_the_wheelbase_and_raise_nothing():
    for lead_sign in (1, -1):
        lt, found = _check(_seen(_rails(0), 2.2, lead_sign), lead_sign)
        a, rho = lt.wheelbase()
        assert a == pytest.approx(2.2, abs=DX / 2) and rho > 0.7 and lt.rails == ("L", "R")
        assert found == []


def test_an_accelerometer_of_the_wrong_sign_is_named_with_its_rail():
    seen = _seen(_rails(0), 2.2)
    seen[(2, "R")] = -seen[(2, "R")]
    lt, found = _check(seen)
    assert len(found) == 1
    assert found[0].startswith("rail R:") and "ACC_W1R_Z or ACC_W2R_Z reads with the wrong sign" in found[0]
    rho = float(found[0].split("correlate at ")[1].split(" ")[0])
    assert rho == pytest.approx(-0.8, abs=0.05)  # 1/(1 + own²): the rail's share of each estimate
    # its summed same-rail correlation is what made the wheelbase unmeasurable
    assert lt.wheelbase()[1] < MIN_CORRELATION


def test_one_wheelset_read_with_the_wrong_sign_names_both_of_its_channels():
    seen = _seen(_rails(0), 2.2)
    for r in "LR":
        seen[(2, r)] = -seen[(2, r)]
    (found,) = _check(seen)[1]
    assert found.startswith("rails L and R:") and "ACC_W2L_Z, ACC_W2R_Z" in found


def test_swapped_vehicle_sides_are_found_across_the_rails():
    seen = _seen(_rails(0), 2.2)
    seen[(1, "L")], seen[(1, "R")] = seen[(1, "R")], seen[(1, "L")]
    (found,) = _check(seen)[1]
    assert "one wheelset's L and R channels are swapped" in found
    assert "ACC_W1L_Z and ACC_W1R_Z, or ACC_W2L_Z and ACC_W2R_Z" in found


def test_one_rail_with_its_wheelset_numbers_swapped_and_both_rails_reversed():
    seen = _seen(_rails(0), 2.2)
    seen[(1, "L")], seen[(2, "L")] = seen[(2, "L")], seen[(1, "L")]
    (found,) = _check(seen)[1]
    assert found.startswith("rail L:") and "ACC_W1L_Z and ACC_W2L_Z are swapped" in found
    # the header puts wheelset 1 ahead, the rails say wheelset 2 is: direction, orientation or numbering
    (found,) = _check(_seen(_rails(0), 2.2, lead_sign=-1), lead_sign=1)[1]
    assert "both rails' estimates match with the two wheelsets' places exchanged" in found
    assert "direction (forward) and orientation (normal)" in found


def test_a_single_rail_on_both_wheelsets_is_checked_too():
    seen = {k: v for k, v in _seen(_rails(0), 2.2).items() if k[1] == "L"}
    seen[(1, "L")] = -seen[(1, "L")]
    lt, found = _check(seen)
    assert lt.rails == ("L",) and len(found) == 1 and "ACC_W1L_Z or ACC_W2L_Z" in found[0]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**16), own=st.floats(0.3, 1.5), wheelbase=st.floats(1.5, 3.5),
       weak=st.floats(0.0, 1.0))
def test_no_rearrangement_is_claimed_for_a_consistent_bogie(seed, own, wheelbase, weak):
    """However noisy each wheelset's own error (``own``) and however weak one rail's common part (``weak``, down
    to none: a rail the model gets wrong), consistent estimates are never refused."""
    rails = _rails(seed, 60.0)
    seen = _seen(rails, wheelbase, own=own, seed=seed + 1)
    for w in (1, 2):  # rail R's common part scaled down on both wheelsets, its own error kept
        seen[(w, "R")] = weak * seen[(w, "R")] + np.random.default_rng(seed + 7 + w).standard_normal(rails["R"].size)
    lt, found = _check(seen)
    assert found == []


def test_independent_wheelsets_are_neither_consistent_nor_refused():
    """Two wheelsets that see nothing in common (a model wrong everywhere, or no rail between them): no lag is
    measured and no channel is blamed."""
    a, b = _rails(0), _rails(1)
    seen = {(1, r): a[r] for r in "LR"} | {(2, r): b[r] for r in "LR"}
    lt, found = _check(seen)
    assert lt.wheelbase()[1] < MIN_CORRELATION and found == []


# --------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def flipped_run(tmp_path_factory):
    from test_estimator_synthetic import control_model, make_run

    def upside_down(ch):
        t, v, u = ch["ACC_W2R_Z"]
        ch["ACC_W2R_Z"] = (t, -v, u)

    return make_run(tmp_path_factory.mktemp("flip"), control_model(), duration_s=20, faults=upside_down,
                    name="upside_down")


@pytest.mark.parametrize("wheelbase", [None, 2.2])
def test_an_upside_down_accelerometer_stops_the_estimate_naming_it(flipped_run, wheelbase):
    """Measured or given wheelbase alike: before this check a measured one failed as 'lead/trail correlation 0.13'
    and a given one let the run through with every vertical-model estimate wrong."""
    from estimator import ChannelError, EstimatorConfig, estimate_run, prepare
    from test_estimator_synthetic import control_model, sensor_table

    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(models=("half", "vertical"),
                                                                         wheelbase_m=wheelbase))
    with pytest.raises(ChannelError, match="ACC_W1R_Z or ACC_W2R_Z reads with the wrong sign") as err:
        estimate_run(flipped_run.path, fm)
    assert "upside_down.mf4" in str(err.value)


def test_the_cli_prints_the_finding_without_a_traceback(flipped_run, tmp_path, capsys):
    from railmodal.cli import main
    from receptance import save_model
    from test_estimator_synthetic import control_model, sensor_table

    model = tmp_path / "hybrid_model.npz"
    save_model(control_model(), model)
    sensors = tmp_path / "sensors.csv"
    sensor_table().to_csv(sensors, index=False)
    code = main(["-q", "field", "estimate", "--run", str(flipped_run.path), "--sensors", str(sensors), "--model",
                 str(model), "--models", "half", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err
    assert "rail R:" in err and "negative sensitivity in the sensor table" in err
    # and the fix it names works: the channel's sensitivity negated, the run goes through
    table = sensor_table()
    table.loc[table["name"] == "ACC_W2R_Z", "sensitivity"] *= -1
    table.to_csv(sensors, index=False)
    code = main(["-q", "field", "estimate", "--run", str(flipped_run.path), "--sensors", str(sensors), "--model",
                 str(model), "--models", "half", "--out", str(tmp_path / "out")])
    assert code == 0, capsys.readouterr().err
