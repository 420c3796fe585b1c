"""Which modes a sensor layout and a record can see, before any measurement.

The response of each mode against the noise and the expected standard errors of its frequency and
damping come from the output spectrum under the simulated excitation (:mod:`twin.design.spectrum`).

A mode is **observable** when its peak stands at least :data:`SNR_LIMIT_DB`
above the noise on some channel (SSI's stabilisation and clustering found
the hydro unit's modes in 12 of 12 one-hour records at 20 dB and more, 6 of
12 at 14 dB, 1 of 12 at 5 dB, none below -19 dB) and the single-mode bound
is within the extraction targets: frequency std at most
:data:`FREQUENCY_STD_LIMIT` of the frequency, damping std at most
:data:`DAMPING_STD_LIMIT` of the damping ratio, and it stands out from the
other modes' response (below).

**Against the other modes.** A mode can stand far above the noise and still
not show in the record: where a stronger mode's flank lies over its peak, the
lower modes' response carries the sampling error of every covariance SSI
uses. The *prominence* (:func:`mode_prominence`) is the mode's peak against
the output PSD without it (the other modes and the noise) at its frequency;
an observable mode needs at least :data:`PROMINENCE_LIMIT_DB` on some
channel. Set from 1-h FMU records of the paper's truth (seed 1) with a 30 nm
pair at the shaft's top: SSI found every mode below 51 Hz, down to 19.1 Hz
at -1.8 dB, and missed 94.6, 97.1 and 97.5 Hz at -6.8, -4.7 and -4.7 dB (all
15-22 dB above the noise); with one more pair at node 22 it found 97.1 and
97.2 Hz (+4.5 and +0.9 dB; 0.04% and 0.00% from the truth) and still missed
the two below -4 dB. One miss the rule does not predict: 97.2 Hz at +0.6 dB
on the first layout, 0.17% from the masked 97.1 Hz (one cluster there). No
node and no sensor noise lifts the 94.6 and 97.5 Hz modes (exciter stub)
above -4 dB under the runner's turbulence.

**Close modes.** Two target modes whose half-power bands overlap and whose
frequencies lie closer than :data:`CLUSTER_SIGMAS` times the root sum of
squares of their expected frequency stds cannot be told apart by their
frequencies on such a record (:func:`mode_clusters`): the table and the
extraction report them as one cluster, and an extracted mode in the
cluster's span counts for it. Whether
SSI separates them depends on their shapes too; the rule says only that the
frequencies will not. On the hydro unit's 8 channels (20 min) the four modes
at 94.6-97.6 Hz form one cluster; with a pair at the shaft's top (30 nm, 1 h,
the paper's truth) only 97.06 and 97.22 Hz (0.17% apart) stay together.
"""

from __future__ import annotations

import functools
import json
import logging
from dataclasses import replace
from pathlib import Path

import numpy as np
import xarray as xr

from twin import __version__
from twin.errors import ModelError, TwinError
from twin.fem import load_model
from twin.fem.model import RotorModel
from twin.fem.truthfile import Truth, truth_from_json
from twin.design.spectrum import (
    Excitation,
    Spectrum,
    partner_mode,
    pole_covariance,
    single_mode_covariance,
    spectrum,
    zeta_frequency_std,
)
from twin.fmu.simulate import system_for
from twin.fmu.truth import MAX_TARGET_DAMPING
from twin.modes.analysis import damping_ratio
from twin.netcdf import global_attrs

log = logging.getLogger(__name__)

#: Largest expected relative frequency std of an observable mode (the extraction target).
FREQUENCY_STD_LIMIT = 0.002
#: Largest expected damping-ratio std of an observable mode, as a fraction of the ratio (the extraction target).
DAMPING_STD_LIMIT = 0.10
#: Smallest peak-to-noise ratio [dB] on the best channel of an observable mode.
SNR_LIMIT_DB = 15.0
#: Smallest prominence [dB] on the best channel of an observable mode: its peak against the other modes' response
#: and the noise (:func:`mode_prominence`; the module docstring has the records it was set from).
PROMINENCE_LIMIT_DB = -3.0
#: Default highest frequency [Hz] of the target modes (capped at 0.4 fs).
DEFAULT_FMAX_HZ = 100.0
#: Target modes closer than this many root-sum-square frequency stds form a cluster (:func:`mode_clusters`).
CLUSTER_SIGMAS = 3.0


def band_top(fmax_hz: float | None, excitation: Excitation) -> float:
    """Highest target frequency [Hz]: ``fmax_hz`` (default 100 Hz), at most 0.4 fs."""
    top = min(DEFAULT_FMAX_HZ if fmax_hz is None else float(fmax_hz), 0.4 * excitation.fs_hz)
    if not top > 0:
        raise ModelError(f"fmax_hz must be positive, got {fmax_hz}")
    return top


def target_modes(poles: np.ndarray, fmax_hz: float) -> np.ndarray:
    """Indices of the oscillating poles damped less than 10% up to ``fmax_hz``, by frequency."""
    idx = np.nonzero(
        (poles.imag > 0) & (poles.imag <= 2 * np.pi * fmax_hz) & (damping_ratio(poles) < MAX_TARGET_DAMPING)
    )[0]
    return idx[np.argsort(poles.imag[idx], kind="stable")]


def observability(
    model: RotorModel,
    excitation: Excitation | None = None,
    *,
    truth: Truth | None = None,
    fmax_hz: float | None = None,
    crb: bool = True,
    command: str = "",
) -> xr.Dataset:
    """Per target mode: response against noise per channel, expected frequency and damping std, verdict.

    Parameters
    ----------
    model : RotorModel
        Its sensors are the layout judged.
    excitation : Excitation, optional
        Turbulence, noise, record length and sampling rate (defaults: those of ``twin simulate``, 20 min).
    truth : Truth, optional
        Judge the truth's system (model plus hidden effects) instead of the model's.
    fmax_hz : float, optional
        Highest target frequency [Hz] (default 100 Hz, at most 0.4 fs).
    crb : bool
        Also the Cramér-Rao bounds (``*_crb``; NaN without, which is about 6 times faster).

    Returns
    -------
    xarray.Dataset
        Over ``mode`` (1-based) and ``channel``: ``snr_db`` (mode, channel), ``best_snr_db``,
        ``prominence_db`` (mode, channel; :func:`mode_prominence`), ``best_prominence_db``,
        ``frequency`` [Hz], ``damping_ratio``, ``frequency_std`` [Hz], ``damping_ratio_std``,
        ``observable`` (bool), ``reason`` and ``cluster`` (:func:`mode_clusters`).

    Examples
    --------
    >>> obs = observability(hydro_unit)
    >>> int(obs.sizes["mode"]), int(obs.observable.sum()) < 15
    (15, True)
    """
    excitation = excitation or Excitation()
    excitation.check()
    if not model.sensors:
        raise ModelError(f"model '{model.name}' declares no [[sensor]]: nothing can be observed")
    top = band_top(fmax_hz, excitation)
    ss = system_for(model, truth, "full", None)
    sp = spectrum(ss, model, excitation)
    targets = target_modes(sp.poles, top)
    lam = sp.poles[targets]
    snr, f_std, z_std, f_crb, z_crb = mode_bounds(sp, targets, excitation.duration_s, crb=crb)
    freq, zeta = lam.imag / (2 * np.pi), damping_ratio(lam)
    best = snr.max(axis=1)
    prominence = mode_prominence(sp, targets)
    best_prominence = prominence.max(axis=1)
    observable, reasons = verdicts(best, f_std / freq, z_std / zeta, best_prominence)
    cluster = mode_clusters(freq, zeta, f_std)
    settings = {
        "turbulence_asd": float(np.sqrt(sp.force_psd)),
        "noise_ratio": excitation.noise_ratio,
        "noise_std_m": sp.noise_std_m,
        "duration_s": excitation.duration_s,
        "fs_hz": excitation.fs_hz,
        "fmax_hz": top,
    }
    sensors = {s.name: s for s in model.sensors}
    return xr.Dataset(
        {
            "snr_db": (
                ("mode", "channel"),
                snr,
                {"units": "dB", "long_name": "peak response of the mode alone against the noise PSD"},
            ),
            "best_snr_db": ("mode", best, {"units": "dB", "long_name": "peak-to-noise ratio on the best channel"}),
            "prominence_db": (
                ("mode", "channel"),
                prominence,
                {
                    "units": "dB",
                    "long_name": "peak response of the mode alone against the PSD of "
                    "the other modes and the noise at its frequency",
                },
            ),
            "best_prominence_db": (
                "mode",
                best_prominence,
                {"units": "dB", "long_name": "prominence on the channel where it is largest"},
            ),
            "frequency": ("mode", freq, {"units": "Hz", "long_name": "damped natural frequency"}),
            "damping_ratio": ("mode", zeta, {"units": "1", "long_name": "damping ratio"}),
            "frequency_std": (
                "mode",
                f_std,
                {"units": "Hz", "long_name": "expected std of the frequency (single-mode bound)"},
            ),
            "damping_ratio_std": (
                "mode",
                z_std,
                {"units": "1", "long_name": "expected std of the damping ratio (single-mode bound)"},
            ),
            "frequency_crb": (
                "mode",
                f_crb,
                {"units": "Hz", "long_name": "Cramér-Rao bound of the frequency std (whole record)"},
            ),
            "damping_ratio_crb": (
                "mode",
                z_crb,
                {"units": "1", "long_name": "Cramér-Rao bound of the damping-ratio std (whole record)"},
            ),
            "observable": ("mode", observable, {"long_name": "the record can determine the mode"}),
            "reason": ("mode", reasons, {"long_name": "why not observable (empty when observable)"}),
            "cluster": (
                "mode",
                cluster,
                {
                    "long_name": "cluster of modes the frequencies cannot tell apart "
                    "(overlapping half-power bands, closer than "
                    f"{CLUSTER_SIGMAS:g} rss frequency stds; 0: none)"
                },
            ),
        },
        coords={
            "mode": ("mode", np.arange(1, len(targets) + 1), {"long_name": "target mode (by frequency)"}),
            "channel": ("channel", list(ss.outputs)),
            "node": ("channel", [sensors[c].node for c in ss.outputs]),
            "direction": ("channel", [sensors[c].direction for c in ss.outputs]),
        },
        attrs={
            "title": f"observability of {model.name}'s target modes",
            "producer": f"twin {__version__} twin.design.observe",
            "model": model.name,
            "model_source": model.source,
            "command": command,
            "method": "Whittle likelihood of the output spectrum (theory, no simulation): single-mode bound and Cramér-Rao bound",
            "excitation": json.dumps(settings),
            "cluster_sigmas": CLUSTER_SIGMAS,
            "rule": (
                f"observable: best peak-to-noise >= {SNR_LIMIT_DB:g} dB, best peak against the other modes' "
                f"response >= {PROMINENCE_LIMIT_DB:g} dB, frequency std <= "
                f"{100 * FREQUENCY_STD_LIMIT:g}% and damping std <= {100 * DAMPING_STD_LIMIT:g}% of the damping ratio"
            ),
            **({"truth": truth.to_json()} if truth is not None else {}),
        },
    )


def mode_clusters(
    frequency_hz: np.ndarray, damping_ratio: np.ndarray, frequency_std_hz: np.ndarray, sigmas: float = CLUSTER_SIGMAS
) -> np.ndarray:
    """Cluster number of each mode (1, 2, ...; 0 for a mode on its own) by frequency.

    Neighbours in frequency join when their half-power bands overlap,
    ``|f_a - f_b| < ζ_a f_a + ζ_b f_b``, and their frequencies are not told
    apart, ``|f_a - f_b| < sigmas sqrt(std_a² + std_b²)`` (single linkage: a
    chain of such pairs is one cluster). The first condition keeps a mode
    the record hardly informs (a huge std) from joining modes far outside
    its resonance.

    Examples
    --------
    >>> f, zeta = np.array([10.0, 97.06, 97.22, 97.5]), np.array([0.01, 0.022, 0.022, 0.037])
    >>> mode_clusters(f, zeta, np.array([0.01, 0.08, 0.03, 0.03]))
    array([0, 1, 1, 0])
    """
    f = np.asarray(frequency_hz, dtype=float)
    half = f * np.asarray(damping_ratio, dtype=float)
    std = np.asarray(frequency_std_hz, dtype=float)
    order = np.argsort(f, kind="stable")
    gap = np.diff(f[order])
    with np.errstate(invalid="ignore"):
        close = (gap < half[order][:-1] + half[order][1:]) & (gap < sigmas * np.hypot(std[order][:-1], std[order][1:]))
    out = np.zeros(len(f), dtype=int)
    label = 0
    for i, joined in enumerate(close):
        if joined:
            if out[order[i]] == 0:
                label += 1
                out[order[i]] = label
            out[order[i + 1]] = out[order[i]]
    return out


def mode_peak(sp: Spectrum, targets: np.ndarray) -> np.ndarray:
    """PSD [m²/Hz] of each target mode alone at its peak, per channel, ``(n_modes, n_channels)``."""
    lam = sp.poles[targets]
    peak = (
        np.abs(sp.c[:, targets].T) ** 2
        * np.sum(np.abs(sp.b[targets]) ** 2, axis=1)[:, None]
        * sp.force_weight(lam.imag / (2 * np.pi))[:, None]
    )
    return np.maximum(peak / lam.real[:, None] ** 2, 1e-300)


def mode_snr(sp: Spectrum, targets: np.ndarray) -> np.ndarray:
    """Peak of each target mode alone against the noise PSD per channel [dB], ``(n_modes, n_channels)``."""
    return 10 * np.log10(mode_peak(sp, targets) / sp.noise_psd)


def mode_prominence(sp: Spectrum, targets: np.ndarray) -> np.ndarray:
    """Peak of each target mode alone against everything else at its frequency, per channel [dB].

    Everything else is the output PSD without the mode (and its conjugate):
    the other modes' response and the noise. Where the other modes' response
    is negligible this is the peak-to-noise ratio (:func:`mode_snr`); where a
    stronger mode's flank lies over the peak it is what the record shows of
    the mode. Shape ``(n_modes, n_channels)``.

    Examples
    --------
    >>> from twin.fmu.truth import model_state_space
    >>> m = hydro_unit
    >>> sp = spectrum(model_state_space(m, "modal", 60.0), m, Excitation())
    >>> k = target_modes(sp.poles, 60.0)
    >>> bool((mode_prominence(sp, k) <= mode_snr(sp, k) + 1e-9).all())
    True
    """
    peak = mode_peak(sp, targets)
    out = np.empty_like(peak)
    for i, k in enumerate(targets):
        keep = np.ones(len(sp.poles), dtype=bool)
        keep[[k, partner_mode(sp, k)]] = False
        others = replace(sp, poles=sp.poles[keep], c=sp.c[:, keep], b=sp.b[keep])
        background = np.real(np.diagonal(others.psd([sp.poles[k].imag / (2 * np.pi)])[0]))
        out[i] = 10 * np.log10(peak[i] / background)
    return out


def mode_bounds(sp: Spectrum, targets: np.ndarray, duration_s: float, *, crb: bool = True) -> tuple[np.ndarray, ...]:
    """Per target mode: peak-to-noise per channel [dB] and the frequency and damping std bounds.

    Returns
    -------
    (snr_db, frequency_std, damping_ratio_std, frequency_crb, damping_ratio_crb)
        ``snr_db`` of shape ``(n_modes, n_channels)``; the stds [Hz] and [1] from the single-mode
        bound and from the Cramér-Rao bound (NaN with ``crb=False``, which saves its cost).
    """
    n = len(targets)
    snr = mode_snr(sp, targets)
    f_std, z_std, f_crb, z_crb = np.zeros(n), np.zeros(n), np.full(n, np.nan), np.full(n, np.nan)
    for i, k in enumerate(targets):
        lam = sp.poles[k]
        f_std[i], z_std[i] = zeta_frequency_std(lam, single_mode_covariance(sp, k, duration_s))
        if crb:
            f_crb[i], z_crb[i] = zeta_frequency_std(lam, pole_covariance(sp, k, duration_s))
    return snr, f_std, z_std, f_crb, z_crb


def verdicts(
    best_snr_db: np.ndarray, f_rel_std: np.ndarray, zeta_rel_std: np.ndarray, best_prominence_db: np.ndarray
) -> tuple[np.ndarray, list[str]]:
    """Observable or not per mode, with the reasons it is not (see the module docstring).

    ``best_prominence_db`` is :func:`mode_prominence` on the channel where it is largest.
    """
    ok, reasons = [], []
    for snr, fr, zr, pr in zip(best_snr_db, f_rel_std, zeta_rel_std, best_prominence_db):
        why = []
        if snr < SNR_LIMIT_DB:
            why.append(f"peak {snr:.0f} dB against the noise")
        elif pr < PROMINENCE_LIMIT_DB:
            why.append(f"masked: peak {pr:.0f} dB against the other modes' response")
        if fr > FREQUENCY_STD_LIMIT:
            why.append(f"frequency std {100 * fr:.2g}%")
        if zr > DAMPING_STD_LIMIT:
            why.append(f"damping std {100 * zr:.2g}%")
        ok.append(not why)
        reasons.append("; ".join(why))
    return np.array(ok), reasons


def record_observability(
    attrs: dict, channels: list[str], duration_s: float, fmax_hz: float | None = None
) -> xr.Dataset | None:
    """The observability of the target modes in a simulated record, from its attrs (``signals.nc``).

    The model file (``model_source``), the excitation (``settings``: turbulence ASD, noise std [m],
    sampling rate) and the truth the record was simulated from, judged on ``channels`` over
    ``duration_s``. None, with the reason logged, when the attrs do not say (a measured record)
    or the model file is not there any more. The records of a campaign share all of these: the
    judgement is computed once per distinct set (and model file version) and reused.
    """
    source = attrs.get("model_source")
    path = Path(str(source)) if source else None
    if path is None or not path.is_file() or "settings" not in attrs:
        log.info("observability of the target modes not judged: the record does not name its model file and excitation")
        return None
    try:
        settings = json.loads(attrs["settings"])
        excitation = (float(settings["turbulence_asd"]), float(settings["noise_std_m"]), float(settings["fs_hz"]))
    except (KeyError, ValueError, TypeError) as exc:
        log.warning("observability of the target modes not judged: the record's settings do not say %s", exc)
        return None
    key = (
        str(path),
        path.stat().st_mtime_ns,
        excitation,
        None if "truth" not in attrs else str(attrs["truth"]),
        tuple(channels),
        float(duration_s),
        None if fmax_hz is None else float(fmax_hz),
    )
    obs = _judged(*key)
    return None if obs is None else obs.copy(deep=True)  # the cached one stays as judged


@functools.lru_cache(maxsize=8)
def _judged(
    source: str,
    _mtime_ns: int,
    excitation: tuple[float, float, float],
    truth_json: str | None,
    channels: tuple[str, ...],
    duration_s: float,
    fmax_hz: float | None,
) -> xr.Dataset | None:
    """:func:`record_observability` of one set of its inputs (the model file's modification time in the key;
    ``excitation``: turbulence ASD [N/√Hz], noise std [m], sampling rate [Hz])."""
    turbulence_asd, noise_std_m, fs_hz = excitation
    try:
        model = load_model(source)
        sensors = {s.name: s for s in model.sensors}
        if any(c not in sensors for c in channels):
            log.info(
                "observability not judged: channels %s are not sensors of %s",
                [c for c in channels if c not in sensors],
                source,
            )
            return None
        model = replace(model, sensors=[sensors[c] for c in channels])
        truth = None if truth_json is None else truth_from_json(truth_json)
        return observability(
            model,
            Excitation(
                turbulence_asd=turbulence_asd, noise_std_m=noise_std_m or None, duration_s=duration_s, fs_hz=fs_hz
            ),
            truth=truth,
            fmax_hz=fmax_hz,
            crb=False,
        )
    except (TwinError, KeyError, ValueError, TypeError) as exc:
        log.warning("observability of the target modes not judged: %s", exc)
        return None


#: A target mode counts as found when an extracted mode lies within this fraction of its frequency.
FOUND_TOLERANCE = 0.01


def target_summary(obs: xr.Dataset, found_hz: np.ndarray, fmin_hz: float = 0.0) -> list[dict]:
    """Per target mode in the band: frequency, damping, observable (with the reason when not), cluster and found.

    A mode is found when an extracted mode lies within :data:`FOUND_TOLERANCE`
    of its frequency; a member of a cluster (:func:`mode_clusters`) also when
    one lies within the cluster's span (widened by that tolerance), and
    ``in_cluster`` counts the extracted modes there.

    Examples
    --------
    >>> rows = target_summary(observability(hydro_unit, crb=False), [2.92, 10.15, 97.5])
    >>> rows[1]["found"], rows[1]["observable"], rows[0]["found"]
    (True, True, False)
    >>> [(round(r["frequency_hz"], 2), r["found"], r["in_cluster"]) for r in rows if r["cluster"]]
    [(94.59, True, 1), (97.48, True, 1), (97.49, True, 1), (97.63, True, 1)]
    """
    found_hz = np.asarray(found_hz, dtype=float)
    freq = obs.frequency.values
    cluster = obs.cluster.values if "cluster" in obs else np.zeros(len(freq), dtype=int)
    out = []
    for k in range(obs.sizes["mode"]):
        f = float(freq[k])
        if f < fmin_hz:
            continue
        found = bool(np.any(np.abs(found_hz - f) <= FOUND_TOLERANCE * f))
        row = {
            "mode": int(obs.mode[k]),
            "frequency_hz": f,
            "damping_ratio": float(obs.damping_ratio[k]),
            "best_snr_db": float(obs.best_snr_db[k]),
            "observable": bool(obs.observable[k]),
            "reason": str(obs.reason.values[k]),
            "cluster": int(cluster[k]),
        }
        if cluster[k]:
            members = freq[cluster == cluster[k]]
            lo, hi = members.min() * (1 - FOUND_TOLERANCE), members.max() * (1 + FOUND_TOLERANCE)
            row["in_cluster"] = int(np.sum((found_hz >= lo) & (found_hz <= hi)))
            found = found or row["in_cluster"] > 0
        row["found"] = found
        out.append(row)
    return out


def judge_targets(modes: xr.Dataset, signals: xr.Dataset | str | Path) -> xr.Dataset:
    """``modes`` extracted from ``signals`` with the record's target modes judged: observable or not (theory,
    :func:`record_observability`) and found or not (:func:`target_summary`), in the attrs
    ``target_observability`` and ``unobservable_modes`` (JSON) that the comparison reads, and logged.

    The judgement needs the model the record was simulated from (its file, named in the record's attrs) and
    the extraction's band, channels and length (the modes' ``settings``); ``modes`` are returned as they are
    for a record that does not name them (a measured one). The extraction itself never reads a model.
    """
    attrs = dict(signals.attrs) if isinstance(signals, xr.Dataset) else global_attrs(signals)
    try:
        settings = json.loads(modes.attrs["settings"])
        channels, duration_s = list(settings["channels"]), float(settings["duration_s"])
        fmin_hz, fmax_hz = float(settings["fmin_hz"]), float(settings["fmax_hz"])
    except (KeyError, TypeError, ValueError) as exc:
        raise TwinError(
            f"the modes do not say how they were extracted (attr 'settings', as twin.extract writes it): {exc!r}"
        ) from None
    obs = record_observability(attrs, channels, duration_s, fmax_hz)
    if obs is None:
        return modes
    targets = target_summary(obs, modes.frequency.values, fmin_hz)
    for line in unobservable_text(targets):
        log.info(line)
    out = modes.copy()
    out.attrs["target_observability"] = json.dumps(targets)
    out.attrs["unobservable_modes"] = json.dumps([t["frequency_hz"] for t in targets if not t["observable"]])
    return out


def cluster_text(frequency_hz) -> str:
    """The members of one cluster and how far apart they are, for the table and the extraction's lines.

    Examples
    --------
    >>> cluster_text([97.06, 97.22])
    '97.06, 97.22 Hz (0.16% apart, their half-power bands overlap)'
    """
    f = [float(x) for x in frequency_hz]
    return f"{', '.join(f'{x:.2f}' for x in f)} Hz ({100 * (max(f) / min(f) - 1):.2g}% apart, their half-power bands overlap)"


def unobservable_text(targets: list[dict]) -> list[str]:
    """Lines on the target modes a record cannot contain, the clusters, and those it contains but were not found."""
    lines = []
    hidden = [t for t in targets if not t["observable"] and not t["found"]]
    if hidden:
        lines.append(
            "target modes not observable with this layout and record (not measured; not model failures): "
            + "; ".join(f"{t['frequency_hz']:.2f} Hz ({t['reason']})" for t in hidden)
        )
    for label in sorted({t.get("cluster", 0) for t in targets} - {0}):
        members = [t for t in targets if t.get("cluster", 0) == label]
        lines.append(
            f"modes the record cannot tell apart by frequency, reported as one cluster: "
            f"{cluster_text([t['frequency_hz'] for t in members])}; "
            f"{members[0].get('in_cluster', 0)} extracted mode(s) there"
        )
    weak = [t for t in targets if not t["observable"] and t["found"]]
    if weak:
        lines.append(
            "found although below the observability rule (their estimates may scatter beyond their "
            "standard errors): " + "; ".join(f"{t['frequency_hz']:.2f} Hz ({t['reason']})" for t in weak)
        )
    missed = [t for t in targets if t["observable"] and not t["found"]]
    if missed:
        lines.append(
            "observable target modes the extraction did not find: "
            + ", ".join(f"{t['frequency_hz']:.2f} Hz" for t in missed)
        )
    return lines


def target_lines(attrs) -> list[str]:
    """:func:`unobservable_text` of a file's ``target_observability`` attr (none when it has none)."""
    text = attrs.get("target_observability", "")
    return unobservable_text(json.loads(text)) if text else []
