"""Campbell diagram: modal frequencies, whirl and stability over a speed range.

Modes are followed from speed to speed by MAC of their full shapes (not by
frequency order), so crossing forward and backward branches keep their
identity.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr
from twin.progress import bar

from twin.errors import ModelError
from twin.fem.model import RotorModel
from twin.modes.analysis import modal
from twin.modes.pairing import pair_modes

_TRACKED = ("frequency", "damping_ratio", "log_decrement", "whirl", "stable")


def campbell(model: RotorModel, speeds_rpm: Sequence[float], n_modes: int = 10, progress: bool = False) -> xr.Dataset:
    """Modal frequencies and damping of the lowest modes over a range of speeds.

    Parameters
    ----------
    model : RotorModel
    speeds_rpm : sequence of float
        Rotor speeds [rpm], in the order the modes are followed.
    n_modes : int
        Number of modes followed, numbered by frequency at the first speed.
    progress : bool
        Show a progress bar.

    Returns
    -------
    xarray.Dataset
        Dimensions ``speed`` (coordinate ``speed_rpm``) and ``mode``:
        ``frequency`` [Hz], ``damping_ratio``, ``log_decrement``, ``whirl``
        and ``stable``.

    Examples
    --------
    >>> from twin import campbell
    >>> from twin import load_model, shipped_model
    >>> ds = campbell(load_model(shipped_model("ross_reference")), [0, 1000, 2000], n_modes=4)
    >>> ds.frequency.dims, ds.sizes["speed"]
    (('speed', 'mode'), 3)
    """
    speeds = np.asarray(speeds_rpm, dtype=float)
    if speeds.ndim != 1 or speeds.size == 0 or not np.all(np.isfinite(speeds)):
        raise ModelError("speeds_rpm must be a non-empty list of finite speeds")
    previous = modal(model, speeds[0], n_modes=n_modes)
    n_modes = previous.sizes["mode"]
    rows = [{k: previous[k].values for k in _TRACKED}]
    for speed in bar(speeds[1:], desc="Campbell", progress=progress):
        current = modal(model, speed, n_modes=n_modes + 4)
        pairs = pair_modes(previous, current, shape_var="shape")
        order = np.empty(n_modes, dtype=int)
        order[pairs.reference_mode.values - 1] = pairs.other_mode.values - 1
        tracked = current.isel(mode=order).assign_coords(mode=previous["mode"].values)
        rows.append({k: tracked[k].values for k in _TRACKED})
        previous = tracked
    data = {k: (("speed", "mode"), np.stack([r[k] for r in rows])) for k in _TRACKED}
    ds = xr.Dataset(
        data,
        coords={"speed_rpm": ("speed", speeds, {"units": "rpm"}), "mode": np.arange(1, n_modes + 1)},
        attrs={"title": f"Campbell diagram of {model.name}", "model": model.name, "running_speed_rpm": model.speed_rpm},
    )
    ds["frequency"].attrs["units"] = "Hz"
    return ds


def plot_campbell(ds: xr.Dataset, ax=None, harmonics: Sequence[int] = (1,)):
    """Draw a Campbell diagram from :func:`campbell` output.

    Forward whirl is drawn in blue, backward in red, mixed in grey; unstable
    points are marked with black crosses; dashed lines show the running-speed
    harmonics (1X, ...) and a dotted vertical line the running speed.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from twin.modes import plot_campbell
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from twin import load_model, shipped_model
    >>> fig = plot_campbell(campbell(load_model(shipped_model("ross_reference")), [0, 2000, 4000], n_modes=4))
    >>> fig.axes[0].get_xlabel()
    'speed [rpm]'
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 5))
    else:
        fig = ax.figure
    speed = ds["speed_rpm"].values
    colours = {"forward": "tab:blue", "backward": "tab:red", "mixed": "tab:grey"}
    for mode in ds["mode"].values:
        f = ds["frequency"].sel(mode=mode).values
        whirl = ds["whirl"].sel(mode=mode).values
        ax.plot(speed, f, color="0.85", lw=0.8, zorder=1)
        for label, colour in colours.items():
            sel = whirl == label
            ax.scatter(speed[sel], f[sel], s=10, color=colour, zorder=2)
        bad = ~ds["stable"].sel(mode=mode).values.astype(bool)
        ax.scatter(speed[bad], f[bad], marker="x", s=40, color="k", zorder=3)
    for h in harmonics:
        ax.plot(speed, h * speed / 60.0, "k--", lw=0.8)
        ax.annotate(f"{h}X", (speed[-1], h * speed[-1] / 60.0), fontsize=8)
    running = ds.attrs.get("running_speed_rpm")
    if running:
        ax.axvline(running, color="k", ls=":", lw=0.8)
    handles = [plt.Line2D([], [], marker="o", ls="", color=c, label=w) for w, c in colours.items()]
    handles.append(plt.Line2D([], [], marker="x", ls="", color="k", label="unstable"))
    ax.legend(handles=handles, loc="upper left", fontsize=8)
    ax.set_xlabel("speed [rpm]")
    ax.set_ylabel("damped natural frequency [Hz]")
    ax.set_title(ds.attrs.get("title", "Campbell diagram"))
    return fig
