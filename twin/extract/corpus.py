"""Records of structures that are not the twin's, with their exact modes: a check of the extraction.

A :class:`Structure` is a linear model ``M q'' + (C + speed G) q' + K q = B u``
with sensors on some of its degrees of freedom: a shear frame
(:func:`shear_frame`), a cantilever beam (:func:`cantilever`), two modes
close in frequency (:func:`close_pair`), or any matrices
(:func:`from_matrices`, e.g. the ROSS reference rotor). :func:`simulate_record`
drives it with white forces held over each sample (exact for that input, in
its modal coordinates) and returns a record in the ``signal`` layout, each
channel in its quantity and units, with sensor noise at a signal-to-noise
ratio; :func:`truth_modes` gives its modes (damped frequency [Hz], damping
ratio, shapes in displacement at the sensors) and whether each stands out of
the noise; :func:`score` counts what an extraction found, missed and made up.

A mode is *visible* when, at its frequency, its own response's spectral
density on some channel stands :data:`VISIBLE_DB` above the sensor noise's
(and it lies below the band an extraction reads by default,
:data:`twin.extract.steps.DEFAULT_FMAX_FRACTION` of the sampling rate): below that no method can be asked to find it.

Examples
--------
>>> frame = shear_frame(storeys=3, damping_ratio=0.01)
>>> ds = simulate_record(frame, duration_s=60.0, fs_hz=20.0, snr_db=40.0, seed=1)
>>> truth = truth_modes(frame, ds)
>>> ds["signal"].shape, truth["frequency"].values.round(2).tolist(), int(truth["visible"].sum())
((1200, 3), [1.42, 3.97, 5.74], 3)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sl
import scipy.signal as sg
import xarray as xr

from twin import __version__
from twin.extract.steps import DEFAULT_FMAX_FRACTION
from twin.extract.quantities import derivative_orders
from twin.extract.result import attainable_frequency_se
from twin.modes.shapes import mac

#: A mode stands out of the noise when its spectral density at its frequency exceeds the noise's by this [dB].
VISIBLE_DB = 10.0
#: The anti-aliasing filter of the acquisition [fraction of the sampling rate]: modes above it are left out.
ANTI_ALIAS = 0.45
#: The units each quantity is written in (as measurement systems do).
UNITS = {"displacement": ("um", 1e6), "velocity": ("mm/s", 1e3), "acceleration": ("g", 1 / 9.80665)}
#: An estimate is a truth mode's when its frequency is within this fraction (or within :func:`frequency_limit`
#: where statistics allow no closer) and its MAC at least MAC_MIN.
FREQUENCY_TOLERANCE, MAC_MIN = 0.005, 0.95
#: An estimate further than this fraction from every truth mode's frequency is spurious.
SPURIOUS_TOLERANCE = 0.02


@dataclass(frozen=True)
class Structure:
    """A linear structure: mass, damping, stiffness [SI], a gyroscopic matrix times ``speed_rad_s``, the
    degrees of freedom that white forces drive, and the sensors (name: degree of freedom)."""

    name: str
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    sensors: dict[str, int]
    forced: Sequence[int]
    G: np.ndarray | None = None
    speed_rad_s: float = 0.0

    def state_matrix(self) -> np.ndarray:
        """``A = [[0, I], [-M^-1 K, -M^-1 (C + speed G)]]``."""
        n = len(self.M)
        damping = self.C + (0.0 if self.G is None else self.speed_rad_s * self.G)
        return np.block(
            [[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(self.M, self.K), -np.linalg.solve(self.M, damping)]]
        )


def modal_damping(M: np.ndarray, K: np.ndarray, damping_ratio: float | Sequence[float]) -> np.ndarray:
    """The damping matrix that gives every undamped mode of (M, K) the damping ratio(s) given."""
    w2, phi = sl.eigh(K, M)  # mass-normalised: phi^T M phi = I
    zeta = np.broadcast_to(np.asarray(damping_ratio, dtype=float), w2.shape)
    mp = M @ phi
    return mp @ np.diag(2 * zeta * np.sqrt(w2)) @ mp.T


def shear_frame(
    storeys: int = 5, *, mass_kg: float = 1e4, stiffness_n_m: float = 4e6, damping_ratio: float | Sequence[float] = 0.01
) -> Structure:
    """A shear frame: ``storeys`` equal floors on equal columns, a sensor (and a force) on every floor."""
    n = storeys
    M = mass_kg * np.eye(n)
    K = stiffness_n_m * (2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1))
    K[-1, -1] = stiffness_n_m
    sensors = {f"floor{j + 1}": j for j in range(n)}
    return Structure(f"shear frame, {n} storeys", M, modal_damping(M, K, damping_ratio), K, sensors, range(n))


def cantilever(
    elements: int = 10,
    *,
    length_m: float = 2.0,
    ei_n_m2: float = 2e4,
    mass_per_m: float = 5.0,
    damping_ratio: float | Sequence[float] = 0.02,
    sensors: int = 5,
) -> Structure:
    """A clamped-free Euler-Bernoulli beam (consistent mass), lateral sensors at ``sensors`` nodes evenly
    spread to the tip, white lateral forces at every node."""
    le = length_m / elements
    k_e = (
        ei_n_m2
        / le**3
        * np.array(
            [
                [12, 6 * le, -12, 6 * le],
                [6 * le, 4 * le**2, -6 * le, 2 * le**2],
                [-12, -6 * le, 12, -6 * le],
                [6 * le, 2 * le**2, -6 * le, 4 * le**2],
            ]
        )
    )
    m_e = (
        mass_per_m
        * le
        / 420
        * np.array(
            [
                [156, 22 * le, 54, -13 * le],
                [22 * le, 4 * le**2, 13 * le, -3 * le**2],
                [54, 13 * le, 156, -22 * le],
                [-13 * le, -3 * le**2, -22 * le, 4 * le**2],
            ]
        )
    )
    n = 2 * (elements + 1)
    M, K = np.zeros((n, n)), np.zeros((n, n))
    for e in range(elements):
        s = slice(2 * e, 2 * e + 4)
        M[s, s] += m_e
        K[s, s] += k_e
    M, K = M[2:, 2:], K[2:, 2:]  # the clamped end's deflection and slope
    nodes = np.unique(np.round(np.linspace(0, elements, sensors + 1)[1:]).astype(int))
    names = {f"x{int(round(100 * k / elements))}": 2 * (k - 1) for k in nodes}
    return Structure(
        f"cantilever, {elements} elements", M, modal_damping(M, K, damping_ratio), K, names, range(0, n - 2, 2)
    )


def close_pair(
    frequency_hz: float = 5.0, separation: float = 0.01, damping_ratio: float = 0.005, sensors: int = 3
) -> Structure:
    """Two modes ``separation`` apart in frequency (two unit masses whose in-phase and out-of-phase modes
    are set apart), seen by ``sensors`` channels: the two masses and, beyond two, light masses on stiff
    springs to one of them (their own modes 40 times higher), which follow it."""
    w1, w2 = 2 * np.pi * frequency_hz, 2 * np.pi * frequency_hz * (1 + separation)
    phi = np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2)  # mass-normalised shapes of unit masses
    size = max(sensors, 2)
    big_m, big_k = np.eye(size), np.zeros((size, size))
    big_k[:2, :2] = phi @ np.diag([w1**2, w2**2]) @ phi.T
    for j in range(2, size):  # a light mass on a stiff spring to mass j % 2 follows it below its own mode
        big_m[j, j] = 1e-4
        kk = 1e-4 * (2 * np.pi * 40 * frequency_hz) ** 2
        big_k[j, j] += kk
        big_k[j % 2, j % 2] += kk
        big_k[j, j % 2] -= kk
        big_k[j % 2, j] -= kk
    C = modal_damping(big_m, big_k, damping_ratio)
    names = {f"s{j + 1}": j for j in range(size)[:sensors]}
    return Structure(f"two modes {separation:.1%} apart", big_m, C, big_k, names, [0, 1])


def from_matrices(
    name: str,
    M: np.ndarray,
    C: np.ndarray,
    K: np.ndarray,
    sensors: dict[str, int],
    forced: Sequence[int],
    G: np.ndarray | None = None,
    speed_rad_s: float = 0.0,
) -> Structure:
    """Any model given by its matrices (e.g. a rotor from another code)."""
    return Structure(
        name,
        *(np.asarray(a, dtype=float) for a in (M, C, K)),
        dict(sensors),
        list(forced),
        None if G is None else np.asarray(G, dtype=float),
        float(speed_rad_s),
    )


def _eig(structure: Structure):
    lam, vec = np.linalg.eig(structure.state_matrix())
    if np.any(lam.real >= 0):
        raise ValueError(f"{structure.name}: not stable (a pole with real part {lam.real.max():.3g} 1/s)")
    return lam, vec


def simulate_record(
    structure: Structure,
    *,
    duration_s: float,
    fs_hz: float,
    snr_db: float = 40.0,
    quantities: str | Sequence[str] = "displacement",
    seed: int = 0,
    rms_m: float = 1e-5,
) -> xr.Dataset:
    """A record of ``structure`` driven by white forces held over each sample, plus white sensor noise.

    The record is what an acquisition with an anti-aliasing filter at :data:`ANTI_ALIAS` of the rate takes:
    the modes above the filter are left out of the response (else a beam's fourth mode at 304 Hz, sampled
    at 400 Hz, would stand in the record at 96 Hz).

    Parameters
    ----------
    duration_s, fs_hz : float
        Length [s] and sampling rate [Hz].
    snr_db : float
        Each channel's signal-to-noise ratio [dB] (its response's std over the noise's).
    quantities : str or sequence of str
        Every channel's quantity, or each one's (displacement, velocity, acceleration); written in
        :data:`UNITS` (µm, mm/s, g).
    seed : int
        Seed of the forces and the noise.
    rms_m : float
        The forces are scaled so that the largest displacement at a sensor has this RMS [m].
    """
    rng = np.random.default_rng(seed)
    n_t, h = int(round(duration_s * fs_hz)), 1.0 / fs_hz
    lam, vec = _eig(structure)
    dofs = np.array(list(structure.sensors.values()))
    qs = [quantities] * len(dofs) if isinstance(quantities, str) else list(quantities)
    orders = derivative_orders(qs)
    gains = _modal_inputs(structure, vec)
    u = rng.standard_normal((len(structure.forced), n_t))
    y = np.zeros((n_t, len(dofs)))
    x_disp = np.zeros((n_t, len(dofs)))
    for i, li in enumerate(lam):
        if abs(li.imag) / (2 * np.pi) > ANTI_ALIAS * fs_hz:  # the acquisition's anti-aliasing filter
            continue
        drive = (np.exp(li * h) - 1) / li * (gains[i] @ u)  # the sample's held force, integrated exactly
        z = sg.lfilter([0.0, 1.0], [1.0, -np.exp(li * h)], drive)
        shape = vec[dofs, i]
        x_disp += np.real(z[:, None] * shape)
        y += np.real(z[:, None] * (shape * li**orders))
    accel = orders == 2  # an accelerometer feels the force directly too
    if accel.any():
        direct = _accelerations_per_force(structure) @ u
        y[:, accel] += direct[dofs[accel]].T
    scale = rms_m / x_disp.std(axis=0).max()
    y *= scale
    noise_std = y.std(axis=0) * 10 ** (-snr_db / 20)
    y += noise_std * rng.standard_normal(y.shape)
    units = [UNITS[q][0] for q in qs]
    factors = np.array([UNITS[q][1] for q in qs])
    attrs = {
        "sampling_rate": float(fs_hz),
        "title": f"{structure.name}: simulated record",
        "producer": f"twin {__version__} twin.extract.corpus",
        "structure": structure.name,
        "snr_db": float(snr_db),
        "seed": int(seed),
        "force_scale": float(scale),
        "noise_std_si": noise_std.tolist(),
    }
    return xr.Dataset(
        {"signal": (("time", "channel"), y * factors)},
        coords={
            "time": ("time", np.arange(n_t) * h, {"units": "s"}),
            "channel": list(structure.sensors),
            "quantity": ("channel", qs),
            "units": ("channel", units),
        },
        attrs=attrs,
    )


def _modal_inputs(structure: Structure, vec: np.ndarray) -> np.ndarray:
    """How the white forces drive each state mode: ``V^-1 B``, ``B = [0; M^-1 F]``."""
    per_force = _accelerations_per_force(structure)
    return np.linalg.solve(vec, np.vstack([np.zeros_like(per_force), per_force]))


def _accelerations_per_force(structure: Structure) -> np.ndarray:
    """``M^-1 F``: the accelerations of the degrees of freedom per unit of each white force."""
    n, forced = len(structure.M), np.asarray(structure.forced)
    F = np.zeros((n, len(forced)))
    F[forced, np.arange(len(forced))] = 1.0
    return np.linalg.solve(structure.M, F)


def frequency_limit(frequency_hz, damping_ratio, duration_s: float) -> np.ndarray:
    """The relative frequency error an estimate may have [fraction]: :data:`FREQUENCY_TOLERANCE`, or three
    times the standard error that one record of ``duration_s`` allows, where that is wider: the asymptotic
    spread of a lone mode's angular frequency estimated from its response to white noise
    (:func:`twin.extract.result.attainable_frequency_se`), ``sqrt(zeta / (pi f T))`` of the frequency (a
    5%-damped 0.6 Hz mode in 300 s is known to 0.9% at best).

    Examples
    --------
    >>> frequency_limit([0.6, 6.0], [0.05, 0.001], 300.0).round(4).tolist()
    [0.0282, 0.005]
    """
    w = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    relative = attainable_frequency_se(np.asarray(damping_ratio, dtype=float) * w, duration_s) / w
    return np.maximum(FREQUENCY_TOLERANCE, 3 * relative)


def truth_modes(structure: Structure, record: xr.Dataset | None = None) -> xr.Dataset:
    """The structure's modes (upper half plane): damped frequency [Hz], damping ratio, sensor shapes in
    displacement, and, given the record :func:`simulate_record` made, whether each is visible."""
    lam, vec = _eig(structure)
    keep = np.flatnonzero(lam.imag > 0)
    keep = keep[np.argsort(lam[keep].imag)]
    dofs = np.array(list(structure.sensors.values()))
    shapes = vec[np.ix_(dofs, keep)].T
    freq = lam[keep].imag / (2 * np.pi)
    ds = xr.Dataset(
        {
            "frequency": ("mode", freq, {"units": "Hz", "long_name": "damped natural frequency"}),
            "damping_ratio": ("mode", -lam[keep].real / np.abs(lam[keep])),
            "sensor_shape": (("mode", "channel"), shapes),
        },
        coords={"mode": np.arange(len(keep)), "channel": list(structure.sensors)},
        attrs={"structure": structure.name},
    )
    if record is not None:
        ds["visible"] = ("mode", _visible(structure, record, lam, vec, keep))
        duration = record.sizes["time"] / float(record.attrs["sampling_rate"])
        ds["frequency_tolerance"] = ("mode", frequency_limit(freq, ds["damping_ratio"].values, duration))
    return ds


def _visible(structure, record, lam, vec, keep) -> np.ndarray:
    fs = float(record.attrs["sampling_rate"])
    h = 1.0 / fs
    orders = derivative_orders([str(q) for q in record["quantity"].values])
    dofs = np.array(list(structure.sensors.values()))
    gains = _modal_inputs(structure, vec)
    scale = float(record.attrs["force_scale"])
    noise_psd = np.asarray(record.attrs["noise_std_si"]) ** 2 * h
    out = np.zeros(len(keep), dtype=bool)
    for j, i in enumerate(keep):
        li = lam[i]
        wi = li.imag
        drive = np.abs((np.exp(li * h) - 1) / li) ** 2 * np.sum(np.abs(gains[i]) ** 2) * scale**2
        psd_z = drive * h / np.abs(1 - np.exp(li * h) * np.exp(-1j * wi * h)) ** 2
        psd = np.abs(vec[dofs, i] * li**orders) ** 2 * psd_z
        out[j] = wi / (2 * np.pi) < DEFAULT_FMAX_FRACTION * fs and np.max(psd / noise_psd) >= 10 ** (VISIBLE_DB / 10)
    return out


def score(frequency_hz: np.ndarray, shapes: np.ndarray | None, truth: xr.Dataset) -> dict:
    """What an extraction found of the truth's visible modes (frequency within the truth's
    ``frequency_tolerance``, else :data:`FREQUENCY_TOLERANCE`; MAC at least :data:`MAC_MIN`, shapes in
    displacement at the truth's channels; ``shapes=None`` judges the frequency alone), which it missed, and
    its spurious estimates (further than :data:`SPURIOUS_TOLERANCE` from every truth mode, or a second
    estimate of one mode)."""
    f_est = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
    phi_est = None if shapes is None else np.atleast_2d(np.asarray(shapes))
    tol = (
        truth["frequency_tolerance"].values
        if "frequency_tolerance" in truth
        else np.full(truth.sizes["mode"], FREQUENCY_TOLERANCE)
    )
    f_true, phi_true = truth["frequency"].values, truth["sensor_shape"].values
    visible = truth["visible"].values if "visible" in truth else np.ones(len(f_true), bool)
    used, found, missed, errors = set(), [], [], []
    for j in np.flatnonzero(visible):
        rel = np.abs(f_est / f_true[j] - 1)
        candidates = [
            k
            for k in np.argsort(rel)
            if rel[k] <= tol[j]
            and k not in used
            and (phi_est is None or mac(phi_est[k], phi_true[j]).item() >= MAC_MIN)
        ]
        if candidates:
            used.add(candidates[0])
            found.append(float(f_true[j]))
            errors.append(float(rel[candidates[0]]))
        else:
            missed.append(float(f_true[j]))
    spurious, claimed = [], {int(np.argmin(np.abs(f_est[k] / f_true - 1))) for k in used}
    for k in sorted(set(range(len(f_est))) - used, key=lambda k: f_est[k]):
        rel = np.abs(f_est[k] / f_true - 1)
        j = int(np.argmin(rel))
        if rel[j] > SPURIOUS_TOLERANCE or j in claimed:  # nothing there, or a mode already estimated
            spurious.append(float(f_est[k]))
        claimed.add(j)
    return {"found": found, "missed": missed, "spurious": spurious, "frequency_error": errors}
