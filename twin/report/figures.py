"""Figures of a comparison: error per mode, MAC matrix, measured and model spectra per channel."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from twin.extract.quantities import channel_quantities
from twin.extract.signals import check_record
from twin.netcdf import check_folder


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend: figures for files, no window (on a server or in a test)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def modal_spectrum(poles: np.ndarray, shapes: np.ndarray, frequency_hz: np.ndarray) -> np.ndarray:
    """Displacement spectrum of unit-force, unit-norm modes on each channel, ``(channel, frequency)``.

    ``S_c(f) = Σ_i |ψ_ic|² / |i 2π f − λ_i|²`` (modes uncorrelated and equally
    excited): where the peaks sit and how wide they are, for comparing two
    modal sets by eye.

    Examples
    --------
    >>> s = modal_spectrum(np.array([-1 + 2j * np.pi * 10]), np.array([[1.0]]), np.array([5.0, 10.0, 15.0]))
    >>> int(np.argmax(s[0]))
    1
    """
    jw = 2j * np.pi * np.asarray(frequency_hz)[None, :]
    resp = 1.0 / np.abs(jw - np.asarray(poles)[:, None]) ** 2
    return (np.abs(np.asarray(shapes)) ** 2).T @ resp


def comparison_figures(
    tables: xr.Dataset | Sequence[xr.Dataset],
    directory: str | Path,
    prefix: str = "",
    labels: Sequence[str] | None = None,
    signals: xr.Dataset | None = None,
) -> list[Path]:
    """Write ``errors.png``, ``mac.png`` and ``spectra.png`` of one comparison or several side by side.

    Parameters
    ----------
    tables : Dataset or sequence of Dataset
        Comparisons (:func:`twin.loop.compare.compare`) against the same
        measured modes, e.g. before and after an update: drawn on one scale.
    directory : path
        Created if missing.
    prefix : str
        Put before each file name.
    labels : sequence of str, optional
        One per table (default ``model``, or ``model 1, 2, ...``).
    signals : Dataset, optional
        The record the modes were identified from (``signals.nc``): ``spectra.png`` is then its power
        spectral density per channel with the identified and the model frequencies marked
        (:func:`psd_figure`); without it, the modal spectra rebuilt from the modes (:func:`spectra_figure`).

    Examples
    --------
    >>> import tempfile
    >>> from twin.loop.compare import compare
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> table = compare(model, synthesize_modes(model, samples=10, seed=1))
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     [p.name for p in comparison_figures(table, tmp)]
    ['errors.png', 'mac.png', 'spectra.png']
    """
    tables = [tables] if isinstance(tables, xr.Dataset) else list(tables)
    if labels is None:
        labels = ["model"] if len(tables) == 1 else [f"model {k}" for k in range(1, len(tables) + 1)]
    out_dir = check_folder(directory, make=True)
    return [
        error_figure(tables, labels, out_dir / f"{prefix}errors.png"),
        mac_figure(tables, labels, out_dir / f"{prefix}mac.png"),
        (
            spectra_figure(tables, labels, out_dir / f"{prefix}spectra.png")
            if signals is None
            else psd_figure(signals, tables, labels, out_dir / f"{prefix}spectra.png")
        ),
    ]


def _mode_ticks(table: xr.Dataset) -> list[str]:
    return [f"{int(m)}\n{f:.3g} Hz" for m, f in zip(table["mode"].values, table["measured_frequency"].values)]


def error_figure(tables: Sequence[xr.Dataset], labels: Sequence[str], path: Path) -> Path:
    """Frequency error [%] and damping ratio error [pp] per measured mode, ±1 measurement std as bars."""
    plt = pyplot()
    first = tables[0]
    x = np.arange(first.sizes["mode"])
    fig, (ax_f, ax_z) = plt.subplots(2, 1, figsize=(max(7.0, 0.55 * len(x) + 2), 5.6), sharex=True)
    width = 0.8 / len(tables)
    for k, (table, label) in enumerate(zip(tables, labels)):
        dx = (k - (len(tables) - 1) / 2) * width
        name = f"{label}: E = {100 * table.attrs['error']:.3g}%"
        ax_f.bar(x + dx, 100 * table["frequency_error"].values, width, label=name, color=f"C{k}")
        ax_z.bar(x + dx, 100 * table["damping_error"].values, width, label=name, color=f"C{k}")
    for ax, sigma in ((ax_f, "frequency_sigma"), (ax_z, "damping_sigma")):
        if sigma in first:  # the measurement's own uncertainty, around zero
            ax.errorbar(
                x,
                np.zeros_like(x, dtype=float),
                yerr=100 * first[sigma].values,
                fmt="none",
                ecolor="k",
                capsize=3,
                lw=1,
                label="±1 std of the measured value",
            )
        ax.axhline(0, color="k", lw=0.5)
        ax.grid(True, axis="y", alpha=0.3)
    ax_f.set_ylabel("frequency error\nmodel / measured − 1 [%]")
    ax_z.set_ylabel("damping ratio error\nmodel − measured [pp]")
    ax_z.set_xticks(x, _mode_ticks(first), fontsize=7)
    ax_z.set_xlabel("measured mode")
    ax_f.legend(fontsize=7, loc="best")
    ax_f.set_title("model against measured modes, " + " and ".join(labels), fontsize=10)
    return save_figure(fig, path)


def mac_columns(table: xr.Dataset) -> np.ndarray:
    """The columns of a comparison's MAC matrix worth drawing: the paired model modes and those in the band.

    The band runs up to 10% above the highest measured mode; the model's
    modes far above it (up to kHz) carry nothing the measurement can show.
    """
    f_model = table["model_mode_frequency"].values
    f_top = 1.1 * float(table["measured_frequency"].max())
    return np.union1d(np.flatnonzero((f_model >= 0) & (f_model <= f_top)), table["partner"].values - 1)


def mac_figure(tables: Sequence[xr.Dataset], labels: Sequence[str], path: Path) -> Path:
    """MAC of each measured mode against the model modes near the measured band, the pairing boxed."""
    plt = pyplot()
    fig, axes = plt.subplots(
        1, len(tables), figsize=(4.6 * len(tables) + 1.6, 4.6), squeeze=False, layout="constrained"
    )
    im = None
    for k, (ax, table, label) in enumerate(zip(axes[0], tables, labels)):
        f_model = table["model_mode_frequency"].values
        partner = table["partner"].values - 1
        keep = mac_columns(table)
        matrix = table["mac_matrix"].values[:, keep]
        im = ax.imshow(matrix, vmin=0, vmax=1, cmap="viridis", aspect="auto", origin="lower")
        column = {c: j for j, c in enumerate(keep)}
        for r, c in enumerate(partner):
            ax.add_patch(plt.Rectangle((column[c] - 0.5, r - 0.5), 1, 1, fill=False, ec="red", lw=1.5))
        step = max(1, len(keep) // 24)
        ax.set_xticks(
            np.arange(len(keep))[::step], [f"{f_model[c]:.3g}" for c in keep[::step]], rotation=90, fontsize=7
        )
        ax.set_yticks(np.arange(table.sizes["mode"]), _mode_ticks(table) if k == 0 else [], fontsize=7)
        ax.set_xlabel("model mode frequency [Hz]")
        if k == 0:
            ax.set_ylabel("measured mode")
        ax.set_title(f"{label}: MAC (red: paired)", fontsize=10)
    fig.colorbar(im, ax=axes[0].tolist(), label="MAC [1]")
    return save_figure(fig, path, tight=False)


def spectra_figure(tables: Sequence[xr.Dataset], labels: Sequence[str], path: Path) -> Path:
    """Modal spectra per channel: the measured modes' against each model's."""
    plt = pyplot()
    first = tables[0]
    f_max = 1.1 * float(max(max(t["measured_frequency"].max(), t["model_frequency"].max()) for t in tables))
    freq = np.linspace(0.05, f_max, 4000)
    channels = first["channel"].values
    ncol = 2
    nrow = int(np.ceil(len(channels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(9, 1.8 * nrow + 1.0), sharex=True, squeeze=False)
    s_meas = modal_spectrum(first["measured_pole"].values, first["measured_shape"].values, freq)
    s_mod = [modal_spectrum(t["model_pole"].values, t["model_shape"].values, freq) for t in tables]
    for k, c in enumerate(channels):
        ax = axes.flat[k]
        ax.semilogy(freq, s_meas[k], label="measured modes", lw=1.2, color="k")
        for j, (s, label) in enumerate(zip(s_mod, labels)):
            ax.semilogy(freq, s[k], label=label, lw=1, ls=("--", ":", "-.")[j % 3], color=f"C{j}")
        ax.set_title(str(c), fontsize=8)
    for ax in axes.flat[len(channels) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    fig.supxlabel("frequency [Hz]")
    fig.supylabel("Σ|ψ|² / |i2πf − λ|² [s²]")
    fig.suptitle(
        "modal spectra: each set of poles and unit-norm shapes with equal unit forcing\n"
        "(the measured curve is rebuilt from the identified modes, not the signals' spectrum)",
        fontsize=9,
    )
    return save_figure(fig, path)


#: Length of the PSD's Welch segments in periods of the slowest identified mode (its resolution: a tenth of it).
PSD_SEGMENT_PERIODS = 40


def record_psd(
    signals: xr.Dataset, channels: Sequence[str], slowest_hz: float
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Welch's PSD of the record's ``channels`` (those it has) [µm²/Hz] over frequency [Hz].

    Hann segments of :data:`PSD_SEGMENT_PERIODS` periods of ``slowest_hz`` (a power of two of samples, at
    most the record), half overlapping. Returns the frequencies, the PSD (frequency x channel; of a velocity or
    acceleration channel in (µm/s)²/Hz or (µm/s²)²/Hz, :data:`PSD_UNITS`) and the channels.

    Examples
    --------
    >>> t = np.arange(8192) / 64.0
    >>> ds = xr.Dataset({"displacement": (("time", "channel"), 1e-6 * np.sin(2 * np.pi * 3.0 * t)[:, None]
    ...                  + 1e-8 * np.random.default_rng(0).standard_normal((8192, 1)))},
    ...                 coords={"channel": ["A_x"]}, attrs={"sampling_rate": 64.0})
    >>> freq, psd, channels = record_psd(ds, ["A_x"], 3.0)
    >>> float(freq[np.argmax(psd[:, 0])])
    3.0
    """
    import scipy.signal as sg

    have = set(map(str, signals["channel"].values))
    rec = check_record(signals, "signals", channels=[c for c in channels if c in have])
    nperseg = min(len(rec.y), int(2 ** np.ceil(np.log2(PSD_SEGMENT_PERIODS * rec.fs_hz / max(slowest_hz, 1e-3)))))
    freq, psd = sg.welch(rec.y, fs=rec.fs_hz, nperseg=nperseg, axis=0)
    return freq, 1e12 * psd, rec.channels


#: The PSD's units by a channel's quantity (its SI values times 1e6: µm, µm/s, µm/s²).
PSD_UNITS = {"displacement": "µm²/Hz", "velocity": "(µm/s)²/Hz", "acceleration": "(µm/s²)²/Hz"}


def psd_figure(signals: xr.Dataset, tables: Sequence[xr.Dataset], labels: Sequence[str], path: Path) -> Path:
    """The measured power spectral density of each channel [µm²/Hz], the identified and the model frequencies marked.

    What a monitoring engineer reads: Welch's PSD of the record (Hann segments of
    :data:`PSD_SEGMENT_PERIODS` periods of the slowest identified mode, half overlapping), a black line at each
    identified mode's frequency and a dashed coloured line at each model's partner frequency.
    """
    plt = pyplot()
    first = tables[0]
    f_meas = first["measured_frequency"].values
    f_max = 1.15 * float(max(max(t["measured_frequency"].max(), t["model_frequency"].max()) for t in tables))
    freq, psd, channels = record_psd(signals, [str(c) for c in first["channel"].values], float(f_meas.min()))
    quantities = dict(zip(map(str, signals["channel"].values), channel_quantities(signals, "signals")[1]))
    band = (freq >= 0.5 * float(f_meas.min())) & (freq <= f_max)
    ncol = 2
    nrow = int(np.ceil(len(channels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(9, 1.8 * nrow + 1.0), sharex=True, squeeze=False)
    for k, c in enumerate(channels):
        ax = axes.flat[k]
        ax.loglog(freq[band], psd[band, k], lw=0.8, color="tab:gray", label="measured PSD")
        for j, f in enumerate(f_meas):
            ax.axvline(f, color="k", lw=0.7, label="identified modes" if j == 0 else None)
        for i, (t, label) in enumerate(zip(tables, labels)):
            for j, f in enumerate(t["model_frequency"].values):
                ax.axvline(
                    f, color=f"C{i}", lw=1.0, ls=("--", ":", "-.")[i % 3], label=f"{label} modes" if j == 0 else None
                )
        ax.set_title(
            c if quantities[c] == "displacement" else f"{c} ({quantities[c]}, {PSD_UNITS[quantities[c]]})", fontsize=8
        )
    for ax in axes.flat[len(channels) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    fig.supxlabel("frequency [Hz] (log scale)")
    fig.supylabel("displacement PSD [µm²/Hz]")
    fig.suptitle(
        f"power spectral density per channel (Welch, {freq[1]:.3g} Hz resolution)\n"
        "identified modes: black lines; the model's partner modes: dashed",
        fontsize=9,
    )
    return save_figure(fig, path)


def save_figure(fig, path: Path, tight: bool = True) -> Path:
    """Write ``fig`` to ``path`` (110 dpi, laid out tight unless ``tight`` is False) and close it."""
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=110)
    pyplot().close(fig)
    return path
