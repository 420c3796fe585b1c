"""Stabilisation diagram of an extraction (read back from the modes Dataset)."""

from __future__ import annotations

import numpy as np
import xarray as xr


def plot_stabilisation(modes: xr.Dataset, ax=None):
    """Plot the stabilisation diagram stored in a modes Dataset.

    Poles by model order against frequency: grey dots new, open circles stable
    in frequency (and damping), filled dots fully stable; poles assigned to a
    mode are coloured, harmonics marked with crosses, the identified modes by
    vertical lines.

    Parameters
    ----------
    modes : xarray.Dataset
        Output of :func:`twin.extract.extract` or :func:`twin.modes.read_modes`.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> ds = xr.Dataset({"diagram_order": ("diagram_pole", [2, 4]), "diagram_frequency": ("diagram_pole", [1.0, 1.0]),
    ...                  "diagram_status": ("diagram_pole", [0, 3]), "diagram_mode": ("diagram_pole", [-1, 1]),
    ...                  "frequency": ("mode", [1.0])})
    >>> fig = plot_stabilisation(ds)
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(10, 5.5), layout="constrained")
    else:
        fig = ax.figure
    f = modes["diagram_frequency"].values
    n = modes["diagram_order"].values
    status = modes["diagram_status"].values
    mode = modes["diagram_mode"].values
    free = mode == -1
    ax.scatter(f[free & (status == 0)], n[free & (status == 0)], s=4, c="0.75", label="new pole")
    part = free & (status > 0) & (status < 3)
    ax.scatter(
        f[part],
        n[part],
        s=12,
        facecolors="none",
        edgecolors="0.5",
        linewidths=0.6,
        label="stable frequency (and damping)",
    )
    ax.scatter(f[free & (status == 3)], n[free & (status == 3)], s=8, c="0.35", label="stable, not clustered")
    assigned = mode > 0
    ax.scatter(
        f[assigned],
        n[assigned],
        s=10,
        c=mode[assigned],
        cmap="tab20",
        vmin=1,
        vmax=20,
        label="pole of an identified mode",
    )
    harm = mode == -2
    if harm.any():
        ax.scatter(f[harm], n[harm], s=25, marker="x", c="crimson", label="running-speed harmonic")
    for k, fk in enumerate(np.atleast_1d(modes["frequency"].values)):
        ax.axvline(fk, color="C0", lw=0.6, alpha=0.5, label="identified mode" if k == 0 else None)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("model order")
    ax.set_title(modes.attrs.get("title", "stabilisation diagram"))
    ax.legend(loc="upper right", fontsize=7, framealpha=0.9)
    return fig
