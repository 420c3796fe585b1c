"""The error history of a twin as a file: one row per step, and its bar chart.

The table has the dimension ``step`` with ``action`` (what was done),
``error`` (the overall error E after it, a fraction), ``error_low`` and
``error_high`` (the 90% interval of E over the posterior of the update the
step made, :func:`error_interval`; NaN for a step with no posterior) and
``chi2``; its attrs name the measured modes it was computed against. On disk
it is a plain CSV file that ``pandas.read_csv`` reads as it is:
``step,action,error_percent,chi2,modes,error_low_percent,error_high_percent``
(E in percent, the measured modes' file on every row; files without the two
interval columns, as twin wrote them before, are read too), which the command
line extends one comparison at a time (``twin compare ... --history FILE``):
a history is only meaningful against one set of measured modes, so a
comparison against other modes is refused.
"""

from __future__ import annotations

import csv
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from twin.errors import TwinError
from twin.netcdf import atomic_output

if TYPE_CHECKING:
    from twin.fem.model import RotorModel
    from twin.modes.measured import Measured

COLUMNS = ("step", "action", "error_percent", "chi2", "modes", "error_low_percent", "error_high_percent")
#: The header of the histories written before the error's interval (read as well).
OLD_COLUMNS = COLUMNS[:5]
#: Posterior draws the error's interval is computed at (evenly spaced over all chains' draws).
INTERVAL_DRAWS = 100
#: What a history's steps and columns mean, in a sentence for the tables that show them.
HISTORY_KEY = (
    "Each step is the model after an action: an effect is added at zero, so its step keeps the error until "
    "the update that sizes it; E is the error of the model's poles (inverse-variance weighted RMS of "
    "|model pole - measured pole| / |measured pole|), chi2 the sum of the squared z of the poles' parts"
)


def history_dataset(
    actions: list[str],
    errors: list[float],
    chi2: list[float],
    modes: str = "",
    intervals: Sequence[tuple[float, float] | None] | None = None,
) -> xr.Dataset:
    """The history table over ``step``; ``intervals``: each step's 90% interval of E, or None (NaN).

    Examples
    --------
    >>> h = history_dataset(["start", "update"], [0.08, 0.002], [900.0, 12.0], intervals=[None, (0.002, 0.003)])
    >>> h["error"].values.tolist(), h["error_high"].values.tolist(), h.sizes["step"]
    ([0.08, 0.002], [nan, 0.003], 2)
    """
    bounds = np.full((len(actions), 2), np.nan)
    for k, interval in enumerate(intervals or []):
        if interval is not None:
            bounds[k] = interval
    return xr.Dataset(
        {
            "action": ("step", list(actions)),
            "error": ("step", np.asarray(errors, dtype=float), {"units": "1", "long_name": "overall error E"}),
            "error_low": ("step", bounds[:, 0], {"units": "1", "long_name": "5% quantile of E over the posterior"}),
            "error_high": ("step", bounds[:, 1], {"units": "1", "long_name": "95% quantile of E over the posterior"}),
            "chi2": ("step", np.asarray(chi2, dtype=float)),
        },
        coords={"step": np.arange(len(actions))},
        attrs={"modes": modes},
    )


def write_history(history: xr.Dataset, path: str | Path) -> Path:
    """Write the history as CSV, atomically (a failure leaves the old file as it was)."""
    with atomic_output(path, ".csv.part") as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for k in range(history.sizes["step"]):
            low, high = (float(history[v][k]) if v in history else np.nan for v in ("error_low", "error_high"))
            w.writerow(
                [
                    k,
                    str(history["action"].values[k]),
                    repr(100 * float(history["error"][k])),
                    repr(float(history["chi2"][k])),
                    history.attrs.get("modes", ""),
                    "" if np.isnan(low) else repr(100 * low),
                    "" if np.isnan(high) else repr(100 * high),
                ]
            )
    return path


def read_history(path: str | Path) -> xr.Dataset:
    """Read a history CSV written by :func:`write_history`; a malformed file is a clear error."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as err:
        raise TwinError(f"{path}: cannot read the history ({err.strerror})") from None
    rows = list(csv.reader(lines))
    if not rows or tuple(rows[0]) not in (COLUMNS, OLD_COLUMNS):
        raise TwinError(f"{path}: not a twin history (the header must be {','.join(COLUMNS)})")
    header = rows[0]
    actions, errors, chi2, modes, intervals = [], [], [], set(), []
    for n, row in enumerate(rows[1:], start=2):
        try:
            if len(row) != len(header):
                raise ValueError
            _, action, error, c, m, *bounds = row
            errors.append(float(error) / 100)
            chi2.append(float(c))
            low, high = (float(b) / 100 if b else np.nan for b in bounds) if bounds else (np.nan, np.nan)
        except ValueError:
            raise TwinError(f"{path}: row {n} is not '{','.join(header)}': {','.join(row)}") from None
        actions.append(action)
        modes.add(m)
        intervals.append(None if np.isnan(low) else (low, high))
    if len(modes) > 1:
        raise TwinError(f"{path}: different measured modes in one history ({', '.join(sorted(modes))})")
    return history_dataset(actions, errors, chi2, modes.pop() if modes else "", intervals)


def append_step(path: str | Path, action: str, comparison: xr.Dataset, modes: str) -> xr.Dataset:
    """Add one comparison's error to the history file ``path`` (created if missing); returns the history.

    Examples
    --------
    >>> import tempfile
    >>> table = xr.Dataset(attrs={"error": 0.05, "chi2": 400.0})
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = append_step(f"{tmp}/h.csv", "start", table, "modes.nc")
    ...     h = append_step(f"{tmp}/h.csv", "add magnetic_pull", table, "modes.nc")
    >>> h["action"].values.tolist()
    ['start', 'add magnetic_pull']
    """
    path = Path(path)
    old = read_history(path) if path.exists() else history_dataset([], [], [], modes)
    if old.sizes["step"] and old.attrs["modes"] != modes:
        raise TwinError(
            f"{path}: this history compares against '{old.attrs['modes']}', not '{modes}': "
            "start a new history file for other measured modes"
        )
    before = [None if np.isnan(lo) else (lo, hi) for lo, hi in zip(old["error_low"].values, old["error_high"].values)]
    new = history_dataset(
        [*old["action"].values.tolist(), action],
        [*old["error"].values.tolist(), float(comparison.attrs["error"])],
        [*old["chi2"].values.tolist(), float(comparison.attrs["chi2"])],
        modes,
        [*before, None],
    )
    write_history(new, path)
    return new


def plot_history(history: xr.Dataset, path: str | Path) -> Path:
    """The error E after each step, points joined on a log axis, each labelled with its value.

    Where the history has ``error_low``/``error_high`` (a 90% interval of E
    over an update's posterior, which only an update's step has), they are
    drawn as error bars on those steps, and the legend says which.
    """
    from twin.report.figures import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 3.4), layout="constrained")
    steps = np.arange(history.sizes["step"])
    errors = 100 * history["error"].values
    ax.plot(steps, errors, "o-", color="tab:blue", label="E of the model at the step")
    if "error_low" in history and np.isfinite(history["error_low"].values).any():
        low, high = 100 * history["error_low"].values, 100 * history["error_high"].values
        has = np.isfinite(low) & np.isfinite(high)
        yerr = np.vstack([np.clip(errors - low, 0, None), np.clip(high - errors, 0, None)])[:, has]
        ax.errorbar(
            steps[has],
            errors[has],
            yerr=yerr,
            fmt="none",
            ecolor="tab:orange",
            capsize=4,
            label="90% interval of E over the update's posterior",
        )
    ax.legend(fontsize=8, loc="lower left")
    ax.set_xticks(steps, history["action"].values, rotation=15, fontsize=8)
    ax.set_xlabel("step")
    ax.set_ylabel("error E [%] (log scale)")
    ax.set_yscale("log")
    ax.set_title("error of the model against the measured modes, step by step", fontsize=10)
    for k, e in zip(steps, errors):
        ax.annotate(f"{e:.3g}%", (k, e), textcoords="offset points", xytext=(6, 6), fontsize=8)
    low_y, high_y = ax.get_ylim()
    ax.set_ylim(low_y / 2, high_y * 3)  # room for the labels under the title and for the legend
    ax.set_xlim(-0.4, len(steps) - 0.4)
    ax.grid(True, which="both", alpha=0.3)
    return save_figure(fig, Path(path), tight=False)


def interval_text(interval: tuple[float, float] | None) -> str:
    """An interval of E (fractions) as text in percent; '-' for none.

    Examples
    --------
    >>> interval_text((0.000583, 0.00061)), interval_text(None)
    ('0.0583-0.061', '-')
    """
    return "-" if interval is None else f"{100 * interval[0]:.3g}-{100 * interval[1]:.3g}"


def error_interval(
    model: RotorModel,
    posterior: xr.DataTree | xr.Dataset,
    measured: Measured,
    *,
    draws: int = INTERVAL_DRAWS,
    level: float = 0.90,
) -> tuple[float, float]:
    """The ``level`` interval of the overall error E over an update's posterior.

    E (:func:`twin.loop.compare.compare`) of ``model`` with the values of each of ``draws`` posterior draws
    (evenly spaced over all chains' draws; :func:`twin.update.apply_posterior` of that one draw, a value
    outside its physical bounds put on the bound), and the central ``level`` quantiles of those errors.
    About 30 ms a draw for the hydro unit.

    Parameters
    ----------
    model : RotorModel
        The model the update started from.
    posterior : xarray.DataTree or xarray.Dataset
        The sampler's posterior (:func:`twin.update.update`), calibrated or not.
    measured : Measured
        The measured modes E is computed against.

    Returns
    -------
    (low, high)
        Fractions, as E.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.fem.truthfile import Truth
    >>> from twin.modes.measured import measured_modes
    >>> from twin.update import synthesize_modes
    >>> dry = hydro_unit
    >>> meas = measured_modes(synthesize_modes(dry, Truth((MagneticPull(-1e8),)), n_modes=13, samples=50, seed=3))
    >>> model = dry.with_effects(MagneticPull(0.0))
    >>> draws = np.random.default_rng(0).normal(-1e8, 2e6, (2, 50, 1))
    >>> post = xr.Dataset({"theta": (("chain", "draw", "parameter"), draws)}, coords={"parameter": ["MAG.stiffness"]})
    >>> low, high = error_interval(model, post, meas, draws=20)
    >>> bool(0 < low < high < 0.01)
    True
    """
    from twin.loop.compare import compare
    from twin.update import apply_posterior

    if isinstance(posterior, xr.DataTree):
        posterior = posterior["posterior"].to_dataset()
    samples = posterior.sizes["chain"] * posterior.sizes["draw"]
    picks = np.unique(np.linspace(0, samples - 1, min(int(draws), samples)).round())
    errors = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a draw outside a bound: put on it, as the estimate would be
        for k in picks.astype(int):
            one = posterior.isel(chain=[k // posterior.sizes["draw"]], draw=[k % posterior.sizes["draw"]])
            errors.append(float(compare(apply_posterior(model, one, "mean"), measured).attrs["error"]))
    tail = (1.0 - level) / 2
    low, high = np.quantile(errors, [tail, 1.0 - tail])
    return float(low), float(high)
