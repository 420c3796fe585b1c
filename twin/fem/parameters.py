"""Linear parameters and their footprints.

Every uncertain quantity of the rotor model enters its matrices linearly,

    M(θ) = M0 + Σ θ_k M_k,   C(θ) = C0 + Σ θ_k C_k,
    G(θ) = G0 + Σ θ_k G_k,   K(θ) = K0 + Σ θ_k K_k,

so a parameter is a name, a nominal value, a unit and its *footprint*: the
matrices ``M_k, C_k, G_k, K_k``, each non-zero on a few DOFs only. Footprints
are stored as small dense blocks on explicit DOF indices (:class:`Term`), which
keeps them readable and lets the updater find the parametrised DOF set at once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

#: The four matrices of ``M q'' + (C + Ω G) q' + K q = F``.
MATRIX_KINDS: tuple[str, ...] = ("M", "C", "G", "K")


@dataclass(frozen=True)
class Term:
    """A dense block ``value`` added to matrix ``kind`` at rows/cols ``dofs``.

    Examples
    --------
    >>> from twin.fem import Term
    >>> t = Term("K", (0, 1), [[2.0, 0.5], [-0.5, 3.0]])
    >>> t.to_dense(3)
    array([[ 2. ,  0.5,  0. ],
           [-0.5,  3. ,  0. ],
           [ 0. ,  0. ,  0. ]])
    """

    kind: str
    dofs: tuple[int, ...]
    value: np.ndarray

    def __post_init__(self) -> None:
        if self.kind not in MATRIX_KINDS:
            raise ValueError(f"matrix kind must be one of {MATRIX_KINDS}, got {self.kind!r}")
        value = np.asarray(self.value, dtype=float)
        n = len(self.dofs)
        if value.shape != (n, n):
            raise ValueError(f"term on {n} DOFs needs an {n}x{n} block, got shape {value.shape}")
        object.__setattr__(self, "dofs", tuple(int(d) for d in self.dofs))
        object.__setattr__(self, "value", value)

    def add_to(self, matrix: np.ndarray, scale: float = 1.0) -> None:
        """Add ``scale * value`` into the dense global ``matrix`` in place."""
        idx = np.asarray(self.dofs)
        matrix[np.ix_(idx, idx)] += scale * self.value

    def to_dense(self, n_dof: int) -> np.ndarray:
        """The term as a dense ``n_dof x n_dof`` matrix."""
        out = np.zeros((n_dof, n_dof))
        self.add_to(out)
        return out


@dataclass(frozen=True)
class Parameter:
    """A named model parameter that enters M, C, G or K linearly.

    Parameters
    ----------
    name : str
        Dotted name, owner first, e.g. ``"UGB.kxx"`` or ``"runner.m"``.
    nominal : float
        The value the model file gives (SI units).
    unit : str
        SI unit of the value, e.g. ``"N/m"``.
    terms : tuple of Term
        The footprint: the matrix blocks one unit of this parameter adds.
    description : str
        One line saying what the parameter is physically.
    per_mode : bool
        True for effect parameters that take one value per mode (e.g. the
        added mass of each mode in water); such a parameter is not part of the
        single FEM, see :mod:`twin.fem.effects`.
    bounds : (float, float)
        Physically possible values ``(low, high)`` [SI], infinite where
        there is no limit: a mass or a direct bearing stiffness is not
        negative, a magnetic pull is not positive. Fits and priors keep the
        parameter inside them.

    Examples
    --------
    >>> import numpy as np
    >>> from twin.fem import Parameter
    >>> p = Parameter("B.kxx", 1e6, "N/m", (Term("K", (0,), [[1.0]]),), bounds=(0.0, np.inf))
    >>> p.dofs, p.kinds, p.within(-1.0)
    ((0,), ('K',), False)
    """

    name: str
    nominal: float
    unit: str
    terms: tuple[Term, ...]
    description: str = ""
    per_mode: bool = False
    bounds: tuple[float, float] = (-np.inf, np.inf)
    _dofs: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "nominal", float(self.nominal))
        low, high = (float(b) for b in self.bounds)
        if not low < high:
            raise ValueError(f"parameter '{self.name}': bounds must have low < high, got ({low}, {high})")
        object.__setattr__(self, "bounds", (low, high))
        object.__setattr__(self, "terms", tuple(self.terms))
        dofs = sorted({d for t in self.terms for d in t.dofs})
        object.__setattr__(self, "_dofs", tuple(dofs))

    def within(self, value: float) -> bool:
        """Whether ``value`` [SI] lies inside the physical :attr:`bounds` (ends included)."""
        return bool(self.bounds[0] <= value <= self.bounds[1])

    def bounds_text(self) -> str:
        """The bounds in words, e.g. ``'>= 0'``, ``'<= 0'``, ``'>= -5.47e+07'`` (empty when unbounded)."""
        low, high = self.bounds
        parts = ([f">= {low:.4g}"] if np.isfinite(low) else []) + ([f"<= {high:.4g}"] if np.isfinite(high) else [])
        return " and ".join(parts)

    @property
    def dofs(self) -> tuple[int, ...]:
        """Global DOF indices the footprint touches (rows and columns)."""
        return self._dofs

    @property
    def kinds(self) -> tuple[str, ...]:
        """Which of ``M, C, G, K`` the footprint touches."""
        return tuple(k for k in MATRIX_KINDS if any(t.kind == k for t in self.terms))

    def footprint(self, kind: str, n_dof: int) -> sp.csr_array:
        """The footprint matrix ``kind`` (one of M, C, G, K) as a sparse array."""
        if kind not in MATRIX_KINDS:
            raise ValueError(f"matrix kind must be one of {MATRIX_KINDS}, got {kind!r}")
        rows, cols, vals = [], [], []
        for t in self.terms:
            if t.kind != kind:
                continue
            r, c = np.nonzero(t.value)
            rows.append(np.asarray(t.dofs)[r])
            cols.append(np.asarray(t.dofs)[c])
            vals.append(t.value[r, c])
        if not rows:
            return sp.csr_array((n_dof, n_dof))
        coo = sp.coo_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_dof, n_dof))
        return coo.tocsr()  # duplicates are summed
