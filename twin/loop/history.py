"""The error history of a twin as a file: one row per step, and its bar chart.

The table has the dimension ``step`` with ``action`` (what was done),
``error`` (the overall error E after it, a fraction) and ``chi2``; its attrs
name the measured modes it was computed against. On disk it is a CSV file
(``step,action,error,chi2``, a ``# modes: ...`` first line), which the
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

COLUMNS = ("step", "action", "error", "chi2")


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
        f.write(f"# modes: {history.attrs.get('modes', '')}\n")
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for k in range(history.sizes["step"]):
            w.writerow([k, str(history["action"].values[k]), repr(float(history["error"][k])),
                        repr(float(history["chi2"][k]))])  # fmt: skip
    return path


def read_history(path: str | Path) -> xr.Dataset:
    """Read a history CSV written by :func:`write_history`; a malformed file is a clear error."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as err:
        raise TwinError(f"{path}: cannot read the history ({err.strerror})") from None
    modes = lines[0][len("# modes:"):].strip() if lines and lines[0].startswith("# modes:") else ""
    rows = list(csv.reader(line for line in lines if not line.startswith("#")))
    if not rows or tuple(rows[0]) != COLUMNS:
        raise TwinError(f"{path}: not a twin history (the header must be {','.join(COLUMNS)})")
    actions, errors, chi2 = [], [], []
    for n, row in enumerate(rows[1:], start=2):
        try:
            _, action, error, c = row
            errors.append(float(error))
            chi2.append(float(c))
        except ValueError:
            raise TwinError(f"{path}: row {n} is not 'step,action,error,chi2': {','.join(row)}") from None
        actions.append(action)
    return history_dataset(actions, errors, chi2, modes)


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
    """Bar chart of the error after each step, on a log scale."""
    from twin.loop.plots import _pyplot, _save

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.2))
    errors = 100 * history["error"].values
    ax.bar(range(len(errors)), errors, color="tab:blue")
    ax.set_xticks(range(len(errors)), history["action"].values, rotation=15, fontsize=8)
    ax.set_ylabel("error E [%]")
    ax.set_yscale("log")
    for k, e in enumerate(errors):
        ax.annotate(f"{e:.3g}%", (k, e), ha="center", va="bottom", fontsize=8)
    return _save(fig, Path(path))
