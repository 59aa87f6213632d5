"""Model plots carry the data they claim to show."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ema.frf import FrequencyResponse  # noqa: E402
from receptance.compare import Comparison, frf_errors  # noqa: E402
from receptance.plot_model import plot_channel_errors, plot_comparison, plot_receptances  # noqa: E402


def _comparison():
    f = np.linspace(10, 500, 200)
    rng = np.random.default_rng(0)
    hx = (rng.normal(size=(3, 1, f.size)) + 1j * rng.normal(size=(3, 1, f.size))) * 1e-3
    hm = hx * np.array([1.0, 1.1, 2.0])[:, None, None]
    names = ["a", "b", "c"]
    mx = FrequencyResponse(f, hx, names, ["hammer"])
    mm = FrequencyResponse(f, hm, names, ["hammer"])
    err = frf_errors(hx[:, 0], hm[:, 0])
    table = pd.DataFrame({"channel": names, **err})
    return Comparison(mx, mm, table, (10.0, 500.0), float(np.median(err["db_rms"])))


def test_errors_of_a_scaled_copy_are_the_scale():
    c = _comparison()
    np.testing.assert_allclose(c.channels["db_rms"], 20 * np.log10([1.0, 1.1, 2.0]), atol=1e-12)
    np.testing.assert_allclose(c.channels["rel_error"], [0.0, 0.1, 1.0], atol=1e-12)
    np.testing.assert_allclose(c.channels["frac"], 1.0, atol=1e-12)


def test_comparison_plot_shows_the_worst_channels_with_their_data():
    c = _comparison()
    fig = plot_comparison(c, n_worst=2)
    axes = fig.axes
    assert [ax.get_title().split(":")[0] for ax in axes] == ["c", "b"]
    meas, model = axes[0].get_lines()[:2]
    np.testing.assert_allclose(meas.get_ydata(), np.abs(c.measured.data[2, 0]))
    np.testing.assert_allclose(model.get_ydata(), np.abs(c.model.data[2, 0]))
    bars = plot_channel_errors(c).axes[0].patches
    np.testing.assert_allclose([b.get_height() for b in bars], c.channels["db_rms"])


def test_receptance_plot_draws_each_requested_pair():
    c = _comparison()
    fig = plot_receptances(c.measured, [("a", "hammer"), ("c", "hammer")])
    lines = fig.axes[0].get_lines()
    assert len(lines) == 2
    np.testing.assert_allclose(lines[1].get_ydata(), np.abs(c.measured.data[2, 0]))
