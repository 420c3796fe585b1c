"""Complex mode-shape utilities shared by every stage: normalisation and MAC.

Shapes stay complex everywhere (gyroscopic, cross-coupled rotors have
genuinely complex modes). One normalisation is used throughout the package:
unit Euclidean norm, largest component real and positive.
"""

from __future__ import annotations

import numpy as np


def normalise_shapes(shapes: np.ndarray) -> np.ndarray:
    """Normalise complex shapes along the last axis: unit norm, largest entry real positive.

    Parameters
    ----------
    shapes : array_like, complex, shape (..., n)
        One shape per row (any leading dimensions).

    Returns
    -------
    numpy.ndarray
        The normalised shapes, same shape. All-zero rows stay zero.

    Examples
    --------
    >>> import numpy as np
    >>> from twin.modes import normalise_shapes
    >>> normalise_shapes(np.array([1j, 2j])).round(6)
    array([0.447214+0.j, 0.894427+0.j])
    """
    shapes = np.asarray(shapes, dtype=complex)
    norm = np.linalg.norm(shapes, axis=-1, keepdims=True)
    idx = np.argmax(np.abs(shapes), axis=-1)[..., None]
    pivot = np.take_along_axis(shapes, idx, axis=-1)
    nonzero = norm > 0  # then the pivot is non-zero too
    scale = np.where(nonzero, norm * pivot / np.where(nonzero, np.abs(pivot), 1.0), 1.0)
    return np.where(nonzero, shapes / scale, 0.0)


def normalisation_jacobian(shape: np.ndarray) -> np.ndarray:
    """Linear map of a raw shape error onto the normalised shape's, in real coordinates ``[Re, Im]``.

    :func:`normalise_shapes` scales a shape to unit norm with its largest
    entry real and positive. To first order, a raw error ``δ`` of the
    normalised shape ``ψ`` (reference entry ``ψ_r``) moves it by
    ``δ - Re(ψᴴδ) ψ - i (Im δ_r / ψ_r) ψ``: the part along ``ψ`` is the
    norm's, the part along ``iψ`` the reference's phase. The map has rank
    ``2m - 2``: a scale-free likelihood (the updater's) learns nothing from
    those two directions either.

    Parameters
    ----------
    shape : (m,) complex
        Normalised shape (unit norm, largest entry real positive).

    Returns
    -------
    (2m, 2m) real

    Examples
    --------
    >>> import numpy as np
    >>> psi = np.array([0.8, 0.6j])
    >>> N = normalisation_jacobian(psi)
    >>> np.allclose(N @ np.array([0.8, 0.0, 0.0, 0.6]), 0), np.allclose(N @ np.array([0.0, -0.6, 0.8, 0.0]), 0)
    (True, True)
    """
    shape = np.asarray(shape, dtype=complex)
    m = len(shape)
    ref = int(np.argmax(np.abs(shape)))
    a = np.concatenate([shape.real, shape.imag])
    b = np.concatenate([shape.imag, -shape.real])
    N = np.eye(2 * m) - np.outer(a, a)
    N[:, m + ref] += b / shape[ref].real
    return N


def mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Complex modal assurance criterion between two sets of shapes.

    ``MAC_ij = |a_i^H b_j|^2 / ((a_i^H a_i)(b_j^H b_j))``, 1 for shapes equal up
    to a complex factor, 0 for orthogonal ones.

    Parameters
    ----------
    a : array_like, shape (n_a, n) or (n,)
    b : array_like, shape (n_b, n) or (n,)

    Returns
    -------
    numpy.ndarray, shape (n_a, n_b)
        (a scalar array when both inputs are single shapes)

    Examples
    --------
    >>> import numpy as np
    >>> from twin import mac
    >>> v = np.array([1.0, 1j, 0.5])
    >>> round(float(mac(v, (2 - 3j) * v)), 12)
    1.0
    >>> float(mac([1.0, 0.0], [0.0, 1.0]))
    0.0
    """
    a = np.asarray(a, dtype=complex)
    b = np.asarray(b, dtype=complex)
    single = a.ndim == 1 and b.ndim == 1
    a2, b2 = np.atleast_2d(a), np.atleast_2d(b)
    if a2.shape[-1] != b2.shape[-1]:
        raise ValueError(f"shapes must have the same length to compare, got {a2.shape[-1]} and {b2.shape[-1]}")
    num = np.abs(a2.conj() @ b2.T) ** 2
    den = np.outer(np.sum(np.abs(a2) ** 2, axis=1), np.sum(np.abs(b2) ** 2, axis=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0, num / den, 0.0)
    return out[0, 0] if single else out


def mpc(shapes: np.ndarray) -> np.ndarray:
    """Modal phase collinearity (Pappa et al. 1993) of complex shapes along the last axis.

    1 for a real (standing) mode, 0 for a circular one such as a pure forward
    whirl seen by an x and a y probe.

    Examples
    --------
    >>> float(mpc(np.array([1.0, -2.0]) * (1 + 1j)).round(12))
    1.0
    >>> float(mpc(np.array([1.0, 1j])).round(12))
    0.0
    """
    shapes = np.asarray(shapes, dtype=complex)
    re, im = shapes.real, shapes.imag
    sxx, syy, sxy = np.sum(re * re, -1), np.sum(im * im, -1), np.sum(re * im, -1)
    tr, det = sxx + syy, sxx * syy - sxy**2
    gap = np.sqrt(np.clip(tr**2 - 4 * det, 0, None))  # lambda1 - lambda2 of [[sxx, sxy], [sxy, syy]]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(tr > 0, (gap / tr) ** 2, 1.0)


def mpd(shapes: np.ndarray) -> np.ndarray:
    """Mean phase deviation [deg] (Reynders et al. 2012) of complex shapes along the last axis.

    The amplitude-weighted mean angle between the components and their best
    straight line through the origin of the complex plane: 0 for a real mode,
    45 deg for a circular one.

    Examples
    --------
    >>> float(mpd(np.array([1.0, -2.0]) * (1 + 1j)).round(9))
    0.0
    >>> float(mpd(np.array([1.0, 1j])).round(9))
    45.0
    >>> float(mpd(np.array([1j])))  # one component lies on its own line
    0.0
    """
    shapes = np.asarray(shapes, dtype=complex)
    out = np.empty(shapes.shape[:-1])
    for idx in np.ndindex(out.shape):
        v = shapes[idx]
        _, _, vt = np.linalg.svd(np.column_stack([v.real, v.imag]))  # 2 x 2 even for one component
        v12, v22 = vt[1, 0], vt[1, 1]  # V = vt.T: the direction normal to the best line is V[:, 1]
        amp = np.abs(v)
        with np.errstate(invalid="ignore", divide="ignore"):
            cosang = np.abs(v.real * v22 - v.imag * v12) / (np.hypot(v12, v22) * amp)
        ang = np.degrees(np.arccos(np.clip(np.nan_to_num(cosang, nan=1.0), 0.0, 1.0)))
        out[idx] = np.sum(amp * ang) / np.sum(amp) if amp.sum() > 0 else 0.0
    return out
