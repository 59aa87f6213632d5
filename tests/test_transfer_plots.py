"""Transfer-function plots (thesis Figs. 4.1–4.7): the drawn lines carry the computed data."""

import matplotlib

matplotlib.use("Agg")

import math  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from receptance.robustness import robustness_study  # noqa: E402
from receptance.track import track_receptance  # noqa: E402
from receptance.transfer import (full_vertical_transfer, half_wheelset_transfer,  # noqa: E402
                                 vertical_lateral_transfer)
from test_transfer_functions import lumped_wheelset  # noqa: E402

F = np.linspace(5.0, 600.0, 240)


@pytest.fixture(scope="module")
def pr():
    return lumped_wheelset().pole_residues()


def test_fig_4_1_half_receptances(pr, tmp_path):
    import matplotlib.pyplot as plt

    from receptance.plot_transfer import plot_half_receptances

    ws = lumped_wheelset()
    kh = 1.2e9
    tf = half_wheelset_transfer(pr, F, contact_stiffness=kh)
    fig = plot_half_receptances(tf)
    fig.savefig(tmp_path / "fig41.png")
    assert (tmp_path / "fig41.png").stat().st_size > 10_000
    lines = fig.axes[0].lines
    assert [ln.get_label() for ln in lines] == ["wheel A_3,3", "rail A_RZ", "contact 1/K_H", "sum"]
    a33 = ws.receptance(F, ["contact_L:z"], ["contact_L:z"])[:, 0, 0]
    arz = track_receptance(F, direction="vertical")
    np.testing.assert_allclose(lines[0].get_ydata(), np.abs(a33), rtol=1e-10)
    np.testing.assert_allclose(lines[1].get_ydata(), np.abs(arz), rtol=1e-12)
    np.testing.assert_allclose(lines[2].get_ydata(), 1 / kh, rtol=1e-15)
    np.testing.assert_allclose(lines[3].get_ydata(), np.abs(a33 + arz + 1 / kh), rtol=1e-10)
    np.testing.assert_array_equal(lines[3].get_xdata(), F)
    assert fig.axes[0].get_yscale() == "log"
    plt.close(fig)
    # a rigid contact has no compliance line to draw on a log axis
    fig = plot_half_receptances(half_wheelset_transfer(pr, F, side="R", contact_stiffness=math.inf))
    assert [ln.get_label() for ln in fig.axes[0].lines] == ["wheel A_9,9", "rail A_RZ", "sum"]
    plt.close(fig)


@pytest.mark.parametrize("kind", ["half", "vertical", "vertical_lateral"])
def test_figs_4_2_to_4_4_transfer_terms(pr, kind, tmp_path):
    import matplotlib.pyplot as plt

    from receptance.plot_transfer import plot_transfer

    tf = {"half": lambda: half_wheelset_transfer(pr, F),
          "vertical": lambda: full_vertical_transfer(pr, F),
          "vertical_lateral": lambda: vertical_lateral_transfer(pr, F, theta_l=0.05, theta_r=-0.3)}[kind]()
    fig = plot_transfer(tf)
    fig.savefig(tmp_path / f"{kind}.png")
    lines = fig.axes[0].lines
    T = tf.transfer.data
    assert len(lines) == T.shape[0] * T.shape[1]
    for n, ln in enumerate(lines):
        i, j = divmod(n, T.shape[1])
        np.testing.assert_allclose(ln.get_ydata(), np.abs(T[i, j]), rtol=1e-14)
        assert ln.get_label() == f"{tf.transfer.outputs[i]} ← {tf.transfer.inputs[j]}"
    plt.close(fig)
    fig, ax = plt.subplots()
    assert plot_transfer(tf, db=True, ax=ax) is fig
    np.testing.assert_allclose(ax.lines[-1].get_ydata(), 20 * np.log10(np.abs(T[-1, -1])), rtol=1e-13)
    plt.close(fig)


def test_figs_4_5_to_4_7_spectral_std(pr, tmp_path):
    import matplotlib.pyplot as plt

    from receptance.plot_transfer import plot_spectral_std

    res = robustness_study(pr, F, n_models=6, amplitude=0.1, seed=1, theta_l=0.05, theta_r=-0.3)
    fig = plot_spectral_std(res)
    fig.savefig(tmp_path / "std.png")
    assert len(fig.axes) == 3
    for ax, kind in zip(fig.axes, res.models):
        _, std = res.spread(kind)
        assert len(ax.lines) == 2
        np.testing.assert_array_equal(ax.lines[0].get_ydata(), std[0])
        np.testing.assert_array_equal(ax.lines[1].get_ydata(), std[1])
        assert std[0].max() > 0
    plt.close(fig)
    fig, ax = plt.subplots()
    plot_spectral_std(res, "vertical", relative=True, ax=ax)
    np.testing.assert_allclose(ax.lines[0].get_ydata(), res.spread("vertical")[1][0] / np.abs(res.irregularity[0]),
                               rtol=1e-15)
    with pytest.raises(ValueError, match="model="):
        plot_spectral_std(res, ax=ax)
    with pytest.raises(ValueError, match="not studied"):
        plot_spectral_std(res, "lateral")
    plt.close(fig)


def test_plot_module_does_not_import_matplotlib_at_import():
    import subprocess
    import sys

    code = ("import sys, receptance.plot_transfer, receptance.transfer, receptance.robustness; "
            "print('matplotlib' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
