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
