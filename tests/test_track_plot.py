"""Track receptance plot: the drawn curves are the computed receptances."""

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402

from receptance.plot_track import plot_track_receptance  # noqa: E402
from receptance.track import track_receptance  # noqa: E402


def test_plot_draws_receptance_magnitude_and_phase():
    import matplotlib.pyplot as plt

    f = np.linspace(10, 1000, 200)
    fig = plot_track_receptance(f, supports=("continuous", "discrete"))
    ax_mag, ax_ph = fig.axes[:2]
    assert len(ax_mag.lines) == 4
    v = track_receptance(f, direction="vertical")
    np.testing.assert_allclose(ax_mag.lines[0].get_ydata(), np.abs(v), rtol=1e-12)
    np.testing.assert_allclose(ax_ph.lines[0].get_ydata(), np.degrees(np.angle(v)), rtol=1e-12)
    d = track_receptance(f, direction="lateral", supports="discrete", position=0.5)
    np.testing.assert_allclose(ax_mag.lines[3].get_ydata(), np.abs(d), rtol=1e-12)
    plt.close(fig)
