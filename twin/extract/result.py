"""What an extraction returns: which modes its samples determine, and the ``modes.nc`` Dataset of them.

:func:`pole_determined` drops the clusters whose samples wander beyond their
bandwidth; :func:`extracted_modes` lays out the modes, their samples, their
standard errors (jackknife and model-order parts kept apart) and the
stabilisation diagram as :func:`twin.extract.extract` returns them
(variables: ``docs/guide/extract.md``).
"""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from twin.errors import TwinWarning
from twin.extract.signals import Record
from twin.extract.stabilisation import Diagram
from twin.modes.analysis import damping_ratio
from twin.modes.shapes import mpc, mpd

#: A mode's pole must be known within this fraction of its half-power bandwidth (:func:`pole_determined`).
MAX_POLE_SE = 1.0
#: In a record of few time constants, the frequency's standard error may reach this many times what an
#: ideal estimator attains, ``sqrt(2 |Re lambda| / T)`` [1/s] (:func:`pole_scatter`).
ATTAINABLE_SE_FACTOR = 2.0


def pole_determined(
    poles: np.ndarray,
    sample_poles: np.ndarray,
    missing: np.ndarray | None = None,
    damping_judged: np.ndarray | None = None,
    duration_s: float | None = None,
) -> np.ndarray:
    """Whether each mode's samples pin its pole within its half-power bandwidth.

    The test: the standard error of the pole (complex, ``std / sqrt(J)`` of
    the samples) is below ``|Re λ| = ζ ω``, the half-power half-bandwidth.
    A cluster of the stabilisation diagram can persist over model orders
    and still be no physical mode: between two close modes, or where the
    response is at the noise, the surplus states of high orders fit the
    noise with a pole that wanders from sample to sample by more than its
    own bandwidth (on the hydro unit's 20 min records: 52.17 Hz, ζ = 0.24%,
    1.3 times its bandwidth; on a gyroscopic test rotor 61.9 Hz, 1.3 times).
    A physical mode is measured far better than that: 0.03-0.22 of its
    bandwidth on the same records. Harmonics, undamped on purpose, are told
    apart before this (:mod:`twin.extract.harmonics`).

    A model order whose reduced record has no counterpart of the mode keeps
    its full-record pole in that sample, which pulls the sample toward the
    full-record mean: with a fraction ``m`` of the (sample, order) pairs
    missing, the spread is about ``1 - m`` of what it would be, so the
    standard error is divided by it. (With 99 block rows a noise cluster of
    the KOMA shear frame, 2.66 Hz without a counterpart in 45% of them,
    passed the test without that.)

    Blocks shorter than a few time constants of a lightly damped mode cannot
    tell its damping: each block's estimate of it scatters by more than the
    bandwidth while the frequency is pinned (a 0.2% mode at 8 Hz in 16 s
    blocks: frequency within 0.6 of its bandwidth, damping 1.2 times). For a
    pole whose damping the blocks cannot judge (``damping_judged`` False), the
    test is on the frequency's standard error alone; a noise pole, whose
    frequency wanders too, still fails it.

    A record of few time constants cannot pin even the frequency within the
    bandwidth: a lone mode's angular frequency from a response of ``T``
    seconds to white noise has a standard error of at least ``sqrt(2 |Re λ| / T)``,
    which exceeds ``|Re λ|`` when ``T < 2 / |Re λ|``. Given ``duration_s``, the
    standard error is measured against :data:`ATTAINABLE_SE_FACTOR` times that
    where it is the larger (a 0.2%-damped 0.9 Hz mode in 240 s, 2.7 of its time
    constants, scattered by 1.0 bandwidths and was dropped; the noise poles of
    the same record, 2 to 4 bandwidths, still are). On records of more than
    eight time constants of a pole nothing changes.

    Parameters
    ----------
    poles : (modes,) complex
        Full-record poles [1/s].
    sample_poles : (modes, J) complex
        The jackknife samples of the poles.
    missing : (modes,) float, optional
        Fraction of each mode's (sample, order) pairs without a counterpart (default: none).
    damping_judged : (modes,) bool, optional
        Whether the blocks are long enough to judge each pole's damping (default: all are).
    duration_s : float, optional
        The record's length [s], for the frequency's attainable standard error (default: not used).

    Examples
    --------
    >>> p = np.array([-0.5 + 100j, -0.5 + 300j])
    >>> spread = np.array([[0.1], [5.0]])  # 1/s: the second wanders by 10 bandwidths
    >>> samples = p[:, None] + spread * np.random.default_rng(0).standard_normal((2, 16))
    >>> pole_determined(p, samples)
    array([ True, False])
    """
    return pole_scatter(poles, sample_poles, missing, damping_judged, duration_s) < MAX_POLE_SE


def pole_scatter(
    poles: np.ndarray,
    sample_poles: np.ndarray,
    missing: np.ndarray | None = None,
    damping_judged: np.ndarray | None = None,
    duration_s: float | None = None,
) -> np.ndarray:
    """The pole's standard error over its samples in half-power half-bandwidths ``|Re λ|`` (or in
    :data:`ATTAINABLE_SE_FACTOR` times the frequency's attainable standard error in ``duration_s``, where
    that is larger), as :func:`pole_determined` judges it (its frequency's alone where the damping is not
    judged)."""
    J = sample_poles.shape[-1]
    real = np.var(sample_poles.real, axis=-1, ddof=1)
    if damping_judged is not None:
        real = np.where(damping_judged, real, 0.0)
    se = np.sqrt(real + np.var(sample_poles.imag, axis=-1, ddof=1))
    kept = 1.0 if missing is None else np.clip(1.0 - np.asarray(missing, dtype=float), 1e-12, 1.0)
    return se / np.sqrt(J) / kept / scatter_scale(poles.real, duration_s)


def scatter_scale(decay_rate: np.ndarray, duration_s: float | None = None) -> np.ndarray:
    """What :func:`pole_scatter` measures a pole's standard error against [1/s]: its half-power
    half-bandwidth ``|Re λ|``, or :data:`ATTAINABLE_SE_FACTOR` times the frequency's attainable standard
    error in a record of ``duration_s`` where that is larger.

    >>> float(scatter_scale(-0.02)), float(scatter_scale(-0.02, 200.0))
    (0.02, 0.0282842712474619)
    """
    scale = np.maximum(np.abs(decay_rate), 1e-300)
    if duration_s is None:
        return scale
    return np.maximum(scale, ATTAINABLE_SE_FACTOR * attainable_frequency_se(scale, duration_s))


def attainable_frequency_se(decay_rate: np.ndarray, duration_s: float) -> np.ndarray:
    """The least standard error [rad/s] of a lone mode's angular frequency estimated from ``duration_s`` of
    its response to white noise: ``sqrt(2 |Re λ| / T)``, ``decay_rate = |Re λ| = ζ ω`` [1/s].

    Examples
    --------
    >>> float(attainable_frequency_se(0.02, 200.0))
    0.01414213562373095
    """
    return np.sqrt(2 * np.abs(decay_rate) / float(duration_s))


def frequency_damping_std(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Std (ddof 1, over the last axis) of the damped frequency [Hz] and the damping ratio of poles [1/s]."""
    return np.std(poles.imag / (2 * np.pi), axis=-1, ddof=1), np.std(damping_ratio(poles), axis=-1, ddof=1)


def left_out(
    source: str,
    poles: np.ndarray,
    sample_poles: np.ndarray,
    scatter: np.ndarray,
    damping_judged: np.ndarray,
    duration_s: float | None = None,
) -> list[dict]:
    """The stable poles :func:`pole_determined` leaves out, for the modes file's ``undetermined_poles``, each
    said in a warning naming it, the part of it (frequency or damping) that scattered by ``scatter`` times
    what it was judged against (:func:`pole_scatter`: its bandwidth, or in a record of ``duration_s`` too
    short for that, the standard error such a record allows)."""
    f_se, z_se = (x / np.sqrt(sample_poles.shape[-1]) for x in frequency_damping_std(sample_poles))
    out = []
    for p, s, f, z, ratio, whole in zip(poles, sample_poles, f_se, z_se, scatter, damping_judged):
        u = {
            "frequency_hz": float(p.imag / (2 * np.pi)),
            "damping_ratio": float(damping_ratio(p)),
            "frequency_se_hz": float(f),
            "damping_ratio_se": float(z),
        }
        # which part of the pole scatters most: its imaginary part is the frequency, its real part the damping
        damping_most = whole and np.std(s.real, ddof=1) > np.std(s.imag, ddof=1)
        part = (
            f"its damping (standard error {z:.3g} of a damping ratio {u['damping_ratio']:.3g})"
            if damping_most
            else f"its frequency (standard error {f:.3g} Hz)"
        )
        bound = (
            "the pole's half-power bandwidth"
            if scatter_scale(p.real, duration_s) <= scatter_scale(p.real)
            else f"{ATTAINABLE_SE_FACTOR:g} x the least standard error a {duration_s:g} s record allows"
        )
        warnings.warn(
            f"{source}: {u['frequency_hz']:.4g} Hz left out: stable over the model orders, but {part} "
            f"scatters over the samples by {ratio:.2g} times {bound}, as a noise "
            "pole fitted by surplus states does; if a mode of the structure is there, a longer record (or "
            "fewer samples: --samples) would show it",
            TwinWarning,
            stacklevel=3,
        )
        out.append(u)
    return out


def extracted_modes(
    rec: Record,
    ds: xr.Dataset,
    poles: np.ndarray,
    shapes: np.ndarray,
    sample_p: np.ndarray,
    sample_s: np.ndarray,
    jackknife_p: np.ndarray,
    members: list,
    n_orders: np.ndarray,
    sizes: list[int],
    ref_channel: np.ndarray,
    diag: Diagram,
) -> xr.Dataset:
    """The modes Dataset of an extraction (without its settings and attrs, which :func:`twin.extract.extract` adds).

    ``poles`` (I,) and ``shapes`` (I, channels) are the full-record estimates; ``sample_p`` (I, J) and
    ``sample_s`` (I, J, channels) the samples as written, ``jackknife_p`` (I, J) the poles' jackknife samples
    alone; ``members`` each mode's ``(orders, poles, shapes)`` over the model orders it is averaged over,
    ``n_orders`` how many, ``sizes`` at how many orders it is stable, ``ref_channel`` the channel each shape
    is made real on; ``ds`` is the signals (their channel coordinates are kept) and ``diag`` the
    stabilisation diagram.
    """
    n_modes, J = sample_p.shape
    f_std, z_std = frequency_damping_std(sample_p)
    f_jk, z_jk = (x / np.sqrt(J) for x in frequency_damping_std(jackknife_p))
    f_order, z_order = np.array([frequency_damping_std(p) if len(p) > 1 else (0.0, 0.0) for _, p, _ in members]).T
    order_cov = np.array(
        [np.cov(np.stack([p.real, p.imag])) if len(p) > 1 else np.zeros((2, 2)) for _, p, _ in members]
    )
    ch_coords = {"channel": ("channel", list(rec.channels))}
    if "displacement" in ds:
        src = ds["displacement"]
        for name in ("node", "direction", "location"):
            if name in src.coords and src[name].dims == ("channel",):
                sel = src[name].sel(channel=list(rec.channels)) if "channel" in src.coords else src[name]
                ch_coords[name] = ("channel", sel.values)
    mode_vars = {
        "pole": (("mode", "sample"), sample_p, {"units": "1/s", "long_name": "pole samples"}),
        "shape": (
            ("mode", "sample", "channel"),
            sample_s,
            {
                "units": "1",
                "long_name": "mode shape samples in displacement (unit norm, reference channel real positive)",
            },
        ),
        "frequency": ("mode", poles.imag / (2 * np.pi), {"units": "Hz", "long_name": "damped natural frequency"}),
        "natural_frequency": (
            "mode",
            np.abs(poles) / (2 * np.pi),
            {"units": "Hz", "long_name": "undamped natural frequency"},
        ),
        "damping_ratio": ("mode", damping_ratio(poles), {"units": "1", "long_name": "damping ratio"}),
        "frequency_std": ("mode", f_std, {"units": "Hz", "long_name": "sample std of frequency"}),
        "damping_ratio_std": ("mode", z_std, {"units": "1", "long_name": "sample std of damping ratio"}),
        "frequency_se": (
            "mode",
            f_std / np.sqrt(J),
            {"units": "Hz", "long_name": "standard error of frequency (sample std / sqrt(J))"},
        ),
        "damping_ratio_se": (
            "mode",
            z_std / np.sqrt(J),
            {"units": "1", "long_name": "standard error of damping ratio (sample std / sqrt(J))"},
        ),
        "frequency_se_jackknife": (
            "mode",
            f_jk,
            {"units": "Hz", "long_name": "statistical part of the frequency's standard error (jackknife)"},
        ),
        "damping_ratio_se_jackknife": (
            "mode",
            z_jk,
            {"units": "1", "long_name": "statistical part of the damping ratio's standard error (jackknife)"},
        ),
        "frequency_order_std": (
            "mode",
            f_order,
            {"units": "Hz", "long_name": "std of the frequency over the model orders the mode is averaged over"},
        ),
        "damping_ratio_order_std": (
            "mode",
            z_order,
            {"units": "1", "long_name": "std of the damping ratio over the model orders the mode is averaged over"},
        ),
        "pole_order_cov": (
            ("mode", "pole_part", "pole_part_2"),
            order_cov,
            {
                "units": "1/s^2",
                "long_name": "covariance of the pole's real and imaginary parts over "
                "the model orders the mode is averaged over",
            },
        ),
        "sensor_shape": (("mode", "channel"), shapes, {"units": "1", "long_name": "full-record mode shape"}),
        "MPC": ("mode", mpc(shapes), {"units": "1", "long_name": "modal phase collinearity (1 real, 0 circular)"}),
        "MPD": ("mode", mpd(shapes), {"units": "deg", "long_name": "mean phase deviation (0 real, 45 circular)"}),
        "n_orders": ("mode", n_orders, {"long_name": "number of model orders the mode is averaged over"}),
        "cluster_size": ("mode", np.asarray(sizes), {"long_name": "orders at which the mode is stable"}),
        "reference_channel": (
            "mode",
            np.array(rec.channels)[ref_channel],
            {"long_name": "channel made real and positive in every shape"},
        ),
    }
    diagram_vars = {
        "diagram_order": ("diagram_pole", diag.order, {"long_name": "model order"}),
        "diagram_frequency": ("diagram_pole", diag.frequency_hz, {"units": "Hz"}),
        "diagram_damping_ratio": ("diagram_pole", diag.damping_ratio, {"units": "1"}),
        "diagram_status": (
            "diagram_pole",
            diag.status,
            {"long_name": "0 new, 1 stable frequency, 2 + damping, 3 + shape"},
        ),
        "diagram_mode": (
            "diagram_pole",
            np.where(diag.cluster >= 0, diag.cluster + 1, diag.cluster),
            {"long_name": "mode number of the pole, -1 none, -2 a harmonic"},
        ),
    }
    return xr.Dataset(
        {**mode_vars, **diagram_vars},
        coords={
            "mode": ("mode", np.arange(1, n_modes + 1)),
            "sample": ("sample", np.arange(J)),
            **ch_coords,
            "pole_part": ("pole_part", ["real", "imag"]),
            "pole_part_2": ("pole_part_2", ["real", "imag"]),
        },
    )
