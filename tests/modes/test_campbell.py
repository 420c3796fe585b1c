"""Campbell diagram: tracking by MAC, stability marks, figure."""

import matplotlib
import numpy as np

from twin import campbell, modal
from twin.modes.campbell import plot_campbell

matplotlib.use("Agg")


def test_campbell_follows_modes_and_marks_instability(ross_model):
    speeds = np.linspace(0, 3000, 7)
    ds = campbell(ross_model, speeds, n_modes=6)
    assert ds.frequency.dims == ("speed", "mode") and ds.sizes == {"speed": 7, "mode": 6}
    first = modal(ross_model, speed_rpm=0, n_modes=6)
    np.testing.assert_allclose(ds.frequency.isel(speed=0), first.frequency)
    # the first mode is a forward mode that stays unstable; backward/forward split with speed
    assert not ds.stable.sel(mode=1).any()
    assert (ds.whirl.sel(mode=1) == "forward").all()
    split = np.abs(ds.frequency.sel(mode=4) - ds.frequency.sel(mode=3))
    assert split.values[-1] > split.values[0]
    # each tracked mode is continuous: no jump larger than the speed step can explain
    assert np.all(np.abs(np.diff(ds.frequency.values, axis=0)) < 5.0)


def test_plot_campbell(tmp_path, hydro_unit):
    ds = campbell(hydro_unit, np.linspace(0, 300, 4), n_modes=5)
    fig = plot_campbell(ds, harmonics=(1, 2))
    ax = fig.axes[0]
    assert ax.get_ylabel() == "damped natural frequency [Hz]"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["forward", "backward", "mixed", "unstable"]
    fig.savefig(tmp_path / "c.png")
    assert (tmp_path / "c.png").stat().st_size > 1000
