"""Figures of a comparison: error per mode, MAC matrix, measured and model spectra per channel."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr


def _pyplot():
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


def comparison_figures(table: xr.Dataset, directory: str | Path, prefix: str = "") -> list[Path]:
    """Write ``errors.png``, ``mac.png`` and ``spectra.png`` of a comparison into ``directory``."""
    plt = _pyplot()
    out_dir = Path(directory)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    modes = table["mode"].values
    x = np.arange(len(modes))
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.bar(x - 0.2, 100 * table["frequency_error"].values, 0.4, label="frequency error [%]")
    ax.bar(x + 0.2, 100 * table["damping_error"].values, 0.4, label="damping ratio error [pp]")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xticks(x, [str(m) for m in modes])
    ax.set_xlabel("measured mode")
    ax.set_title(f"model - measured; E = {100 * table.attrs['error']:.2f}%")
    ax.legend(fontsize=8)
    paths.append(_save(fig, out_dir / f"{prefix}errors.png"))
    fig, ax = plt.subplots(figsize=(5, 4.5))
    im = ax.imshow(table["mac_matrix"].values, vmin=0, vmax=1, cmap="viridis", aspect="auto", origin="lower")
    ax.set_xlabel("model mode")
    ax.set_ylabel("measured mode")
    ax.set_xticks(np.arange(table.sizes["mode_model"])[::2], table["mode_model"].values[::2])
    ax.set_yticks(np.arange(table.sizes["mode_measured"]), table["mode_measured"].values)
    fig.colorbar(im, ax=ax, label="MAC")
    paths.append(_save(fig, out_dir / f"{prefix}mac.png"))
    f_max = 1.1 * float(max(table["measured_frequency"].max(), table["model_frequency"].max()))
    freq = np.linspace(0.05, f_max, 4000)
    s_meas = modal_spectrum(table["measured_pole"].values, table["measured_shape"].values, freq)
    s_mod = modal_spectrum(table["model_pole"].values, table["model_shape"].values, freq)
    channels = table["channel"].values
    ncol = 2
    nrow = int(np.ceil(len(channels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(9, 1.8 * nrow + 0.5), sharex=True, squeeze=False)
    for k, c in enumerate(channels):
        ax = axes.flat[k]
        ax.semilogy(freq, s_meas[k], label="measured", lw=1)
        ax.semilogy(freq, s_mod[k], label="model", lw=1, ls="--")
        ax.set_title(str(c), fontsize=8)
    for ax in axes.flat[len(channels):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    fig.supxlabel("frequency [Hz]")
    fig.supylabel("modal spectrum [1]")
    paths.append(_save(fig, out_dir / f"{prefix}spectra.png"))
    return paths


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)
    return path
