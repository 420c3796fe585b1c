"""The error history of a twin as a file: one row per step, and its bar chart.

The table has the dimension ``step`` with ``action`` (what was done),
``error`` (the overall error E after it, a fraction) and ``chi2``; its attrs
name the measured modes it was computed against. On disk it is a plain CSV
file that ``pandas.read_csv`` reads as it is: ``step,action,error_percent,
chi2,modes`` (E in percent, the measured modes' file on every row), which the
command line extends one comparison at a time (``twin compare ... --history
FILE``): a history is only meaningful against one set of measured modes, so
a comparison against other modes is refused.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import xarray as xr

from twin.errors import TwinError
from twin.netcdf import atomic_output

COLUMNS = ("step", "action", "error_percent", "chi2", "modes")


def history_dataset(actions: list[str], errors: list[float], chi2: list[float], modes: str = "") -> xr.Dataset:
    """The history table over ``step``.

    Examples
    --------
    >>> h = history_dataset(["start", "update"], [0.08, 0.002], [900.0, 12.0])
    >>> h["error"].values.tolist(), h.sizes["step"]
    ([0.08, 0.002], 2)
    """
    return xr.Dataset(
        {
            "action": ("step", list(actions)),
            "error": ("step", np.asarray(errors, dtype=float), {"units": "1", "long_name": "overall error E"}),
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
            w.writerow([k, str(history["action"].values[k]), repr(100 * float(history["error"][k])),
                        repr(float(history["chi2"][k])), history.attrs.get("modes", "")])  # fmt: skip
    return path


def read_history(path: str | Path) -> xr.Dataset:
    """Read a history CSV written by :func:`write_history`; a malformed file is a clear error."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as err:
        raise TwinError(f"{path}: cannot read the history ({err.strerror})") from None
    rows = list(csv.reader(lines))
    if not rows or tuple(rows[0]) != COLUMNS:
        raise TwinError(f"{path}: not a twin history (the header must be {','.join(COLUMNS)})")
    actions, errors, chi2, modes = [], [], [], set()
    for n, row in enumerate(rows[1:], start=2):
        try:
            _, action, error, c, m = row
            errors.append(float(error) / 100)
            chi2.append(float(c))
        except ValueError:
            raise TwinError(f"{path}: row {n} is not '{','.join(COLUMNS)}': {','.join(row)}") from None
        actions.append(action)
        modes.add(m)
    if len(modes) > 1:
        raise TwinError(f"{path}: different measured modes in one history ({', '.join(sorted(modes))})")
    return history_dataset(actions, errors, chi2, modes.pop() if modes else "")


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
        raise TwinError(f"{path}: this history compares against '{old.attrs['modes']}', not '{modes}': "
                        "start a new history file for other measured modes")  # fmt: skip
    new = history_dataset([*old["action"].values.tolist(), action],
                          [*old["error"].values.tolist(), float(comparison.attrs["error"])],
                          [*old["chi2"].values.tolist(), float(comparison.attrs["chi2"])], modes)  # fmt: skip
    write_history(new, path)
    return new


def plot_history(history: xr.Dataset, path: str | Path) -> Path:
    """The error E after each step, points joined on a log axis, each labelled with its value.

    Where the history has ``error_low``/``error_high`` (a 90% interval of E
    from the posterior), they are drawn as error bars.
    """
    from twin.loop.plots import _pyplot, _save

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 3.4), layout="constrained")
    steps = np.arange(history.sizes["step"])
    errors = 100 * history["error"].values
    if "error_low" in history and "error_high" in history:
        low, high = 100 * history["error_low"].values, 100 * history["error_high"].values
        yerr = np.vstack([np.clip(errors - low, 0, None), np.clip(high - errors, 0, None)])
        yerr = np.where(np.isfinite(yerr), yerr, 0.0)
        ax.errorbar(steps, errors, yerr=yerr, fmt="o-", color="tab:blue", capsize=4, label="E (90% interval)")
        ax.legend(fontsize=8)
    else:
        ax.plot(steps, errors, "o-", color="tab:blue")
    ax.set_xticks(steps, history["action"].values, rotation=15, fontsize=8)
    ax.set_xlabel("step")
    ax.set_ylabel("error E [%] (log scale)")
    ax.set_yscale("log")
    ax.set_title("error of the model against the measured modes, step by step", fontsize=10)
    for k, e in zip(steps, errors):
        ax.annotate(f"{e:.3g}%", (k, e), textcoords="offset points", xytext=(6, 6), fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, Path(path), tight=False)
