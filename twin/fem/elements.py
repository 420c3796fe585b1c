"""Rotor finite elements: Timoshenko shaft, rigid disk, bearing, thrust bearing.

DOF order per node is ``[x, y, alpha, beta]`` with ``beta = +dx/dz`` and
``alpha = -dy/dz`` (Friswell et al., *Dynamics of Rotating Machines*, 2010,
and ROSS). Node ``n`` owns global DOFs ``4n .. 4n+3``. Each element returns
its fixed contributions as :class:`~twin.fem.parameters.Term` objects and
its linear parameters as :class:`~twin.fem.parameters.Parameter` objects.

The shaft element is built from the planar Timoshenko matrices on
``(w1, θ1, w2, θ2)`` with ``θ = dw/dz``. In the x-z plane these are
``(x1, β1, x2, β2)``; in the y-z plane ``θ = dy/dz = -α`` so the plane
matrices act on ``T (y1, α1, y2, α2)`` with ``T = diag(1, -1, 1, -1)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twin.fem.parameters import Parameter, Term

DOF_NAMES: tuple[str, ...] = ("x", "y", "alpha", "beta")
DOFS_PER_NODE = 4
#: Physical bounds of a mass, an inertia, a direct stiffness or damping (not negative), and of a
#: cross-coupled coefficient (either sign).
POSITIVE = (0.0, np.inf)
UNBOUNDED = (-np.inf, np.inf)

# Positions of the two bending planes inside an 8-DOF element vector
# [x1, y1, a1, b1, x2, y2, a2, b2].
_XZ = np.array([0, 3, 4, 7])  # (x1, beta1, x2, beta2)
_YZ = np.array([1, 2, 5, 6])  # (y1, alpha1, y2, alpha2)
_T = np.diag([1.0, -1.0, 1.0, -1.0])  # y-z plane: theta = -alpha


def node_dofs(node: int) -> tuple[int, int, int, int]:
    """Global DOF indices ``(x, y, alpha, beta)`` of a node.

    Examples
    --------
    >>> node_dofs(2)
    (8, 9, 10, 11)
    """
    base = DOFS_PER_NODE * int(node)
    return (base, base + 1, base + 2, base + 3)


def cowper_shear_factor(poisson: float, inner_diameter: float, outer_diameter: float) -> float:
    """Cowper's (1966) shear coefficient of a hollow circular section.

    ``κ = 6(1+ν)(1+m²)² / ((7+6ν)(1+m²)² + (20+12ν)m²)`` with ``m = d_i/d_o``.

    Examples
    --------
    >>> round(cowper_shear_factor(0.3, 0.0, 1.0), 6)  # solid: 6(1+ν)/(7+6ν)
    0.886364
    """
    m2 = (inner_diameter / outer_diameter) ** 2
    return 6 * (1 + poisson) * (1 + m2) ** 2 / ((7 + 6 * poisson) * (1 + m2) ** 2 + (20 + 12 * poisson) * m2)


@dataclass(frozen=True)
class Material:
    """Linear elastic isotropic material (SI: Pa, Pa, kg/m3)."""

    name: str
    E: float
    G: float
    rho: float

    @property
    def poisson(self) -> float:
        """Poisson's ratio ``E / (2 G) - 1``."""
        return self.E / (2.0 * self.G) - 1.0


@dataclass(frozen=True)
class ShaftElement:
    """Cylindrical, possibly hollow, Timoshenko beam element between nodes n, n+1.

    Shear deformation enters through ``φ = 12 E I / (κ G A L²)`` (Cowper's κ);
    ``shear=False`` gives the Euler-Bernoulli element (φ = 0). The consistent
    mass matrix holds translational and rotary inertia; the gyroscopic matrix
    is twice the rotary-inertia matrix coupled across the two planes.

    Parameters
    ----------
    n : int
        Index of the first node; the element spans nodes ``n`` and ``n + 1``.
    length, outer_diameter, inner_diameter : float
        Geometry [m].
    material : Material
    shear, rotary_inertia, gyroscopic : bool
        Switch the corresponding effect on (default) or off.

    Examples
    --------
    >>> import numpy as np
    >>> from twin.fem import ShaftElement
    >>> steel = Material("steel", 211e9, 81.2e9, 7810.0)
    >>> el = ShaftElement(0, 0.25, 0.05, 0.0, steel)
    >>> K = el.K()
    >>> bool(np.allclose(K, K.T)), bool(np.allclose(el.G(), -el.G().T))
    (True, True)
    """

    n: int
    length: float
    outer_diameter: float
    inner_diameter: float
    material: Material
    shear: bool = True
    rotary_inertia: bool = True
    gyroscopic: bool = True

    @property
    def area(self) -> float:
        """Cross-section area [m²]."""
        return np.pi * (self.outer_diameter**2 - self.inner_diameter**2) / 4.0

    @property
    def second_moment(self) -> float:
        """Diametral second moment of area I [m⁴]."""
        return np.pi * (self.outer_diameter**4 - self.inner_diameter**4) / 64.0

    @property
    def phi(self) -> float:
        """Shear parameter ``φ = 12 E I / (κ G A L²)``; 0 without shear."""
        if not self.shear:
            return 0.0
        mat = self.material
        kappa = cowper_shear_factor(mat.poisson, self.inner_diameter, self.outer_diameter)
        return 12.0 * mat.E * self.second_moment / (kappa * mat.G * self.area * self.length**2)

    @property
    def mass(self) -> float:
        """Total mass of the element [kg]."""
        return self.material.rho * self.area * self.length

    @property
    def dofs(self) -> tuple[int, ...]:
        """Global DOFs of both nodes."""
        return node_dofs(self.n) + node_dofs(self.n + 1)

    # -- planar matrices on (w1, θ1, w2, θ2) ---------------------------------
    def _plane_stiffness(self) -> np.ndarray:
        L, phi = self.length, self.phi
        a = self.material.E * self.second_moment / ((1 + phi) * L**3)
        return a * np.array(
            [
                [12, 6 * L, -12, 6 * L],
                [6 * L, (4 + phi) * L**2, -6 * L, (2 - phi) * L**2],
                [-12, -6 * L, 12, -6 * L],
                [6 * L, (2 - phi) * L**2, -6 * L, (4 + phi) * L**2],
            ]
        )

    def _plane_translational_mass(self) -> np.ndarray:
        L, p = self.length, self.phi
        m1 = 13 / 35 + 7 * p / 10 + p**2 / 3
        m2 = (11 / 210 + 11 * p / 120 + p**2 / 24) * L
        m3 = 9 / 70 + 3 * p / 10 + p**2 / 6
        m4 = (13 / 420 + 3 * p / 40 + p**2 / 24) * L
        m5 = (1 / 105 + p / 60 + p**2 / 120) * L**2
        m6 = (1 / 140 + p / 60 + p**2 / 120) * L**2
        a = self.mass / (1 + p) ** 2
        return a * np.array(
            [
                [m1, m2, m3, -m4],
                [m2, m5, m4, -m6],
                [m3, m4, m1, -m2],
                [-m4, -m6, -m2, m5],
            ]
        )

    def _plane_rotary_mass(self) -> np.ndarray:
        L, p = self.length, self.phi
        r1 = 6 / 5
        r2 = (1 / 10 - p / 2) * L
        r3 = (2 / 15 + p / 6 + p**2 / 3) * L**2
        r4 = (1 / 30 + p / 6 - p**2 / 6) * L**2
        a = self.material.rho * self.second_moment / ((1 + p) ** 2 * L)
        return a * np.array(
            [
                [r1, r2, -r1, r2],
                [r2, r3, -r2, -r4],
                [-r1, -r2, r1, -r2],
                [r2, -r4, -r2, r3],
            ]
        )

    @staticmethod
    def _both_planes(plane: np.ndarray) -> np.ndarray:
        out = np.zeros((8, 8))
        out[np.ix_(_XZ, _XZ)] = plane
        out[np.ix_(_YZ, _YZ)] = _T @ plane @ _T
        return out

    # -- 8x8 element matrices -------------------------------------------------
    def K(self) -> np.ndarray:
        """Element stiffness matrix (8x8)."""
        return self._both_planes(self._plane_stiffness())

    def M(self) -> np.ndarray:
        """Element consistent mass matrix (8x8), translational + rotary."""
        plane = self._plane_translational_mass()
        if self.rotary_inertia:
            plane = plane + self._plane_rotary_mass()
        return self._both_planes(plane)

    def G(self) -> np.ndarray:
        """Element gyroscopic matrix (8x8, skew-symmetric), per rad/s of speed."""
        out = np.zeros((8, 8))
        if not self.gyroscopic:
            return out
        rot = self._plane_rotary_mass()
        out[np.ix_(_XZ, _YZ)] = 2.0 * rot @ _T
        out[np.ix_(_YZ, _XZ)] = -2.0 * _T @ rot
        return out

    def terms(self) -> list[Term]:
        """Fixed contributions of the element to the global M, G, K."""
        return [Term("M", self.dofs, self.M()), Term("G", self.dofs, self.G()), Term("K", self.dofs, self.K())]


def _single_entry(kind: str, dofs: tuple[int, int], row: int, col: int) -> Term:
    block = np.zeros((2, 2))
    block[row, col] = 1.0
    return Term(kind, dofs, block)


@dataclass(frozen=True)
class Disk:
    """Rigid disk at a node: mass ``m`` [kg], diametral and polar inertia ``Id``, ``Ip`` [kg m²].

    ``M = diag(m, m, Id, Id)`` on ``[x, y, alpha, beta]``; gyroscopic
    ``G[alpha, beta] = +Ip``, ``G[beta, alpha] = -Ip``. All three values are
    linear parameters ``<name>.m``, ``<name>.Id``, ``<name>.Ip``.

    Examples
    --------
    >>> from twin.fem import Disk
    >>> [p.name for p in Disk("runner", 3, 85e3, 2e4, 4e4).parameters()]
    ['runner.m', 'runner.Id', 'runner.Ip']
    """

    name: str
    node: int
    m: float
    Id: float
    Ip: float

    def parameters(self) -> list[Parameter]:
        """The disk's linear parameters with their footprints."""
        x, y, a, b = node_dofs(self.node)
        gyro = np.array([[0.0, 1.0], [-1.0, 0.0]])
        return [
            Parameter(
                f"{self.name}.m", self.m, "kg", (Term("M", (x, y), np.eye(2)),), f"mass of {self.name}", bounds=POSITIVE
            ),
            Parameter(
                f"{self.name}.Id",
                self.Id,
                "kg m^2",
                (Term("M", (a, b), np.eye(2)),),
                f"diametral moment of inertia of {self.name}",
                bounds=POSITIVE,
            ),
            Parameter(
                f"{self.name}.Ip",
                self.Ip,
                "kg m^2",
                (Term("G", (a, b), gyro),),
                f"polar moment of inertia of {self.name} (gyroscopic)",
                bounds=POSITIVE,
            ),
        ]


#: The eight bearing coefficients, with (matrix, row, col) on [x, y].
BEARING_COEFFICIENTS: dict[str, tuple[str, int, int]] = {
    "kxx": ("K", 0, 0),
    "kxy": ("K", 0, 1),
    "kyx": ("K", 1, 0),
    "kyy": ("K", 1, 1),
    "cxx": ("C", 0, 0),
    "cxy": ("C", 0, 1),
    "cyx": ("C", 1, 0),
    "cyy": ("C", 1, 1),
}


@dataclass(frozen=True)
class Bearing:
    """Grounded radial bearing with 8 linear coefficients on ``[x, y]``.

    The force on the shaft is ``-[[kxx, kxy], [kyx, kyy]] [x, y] -
    [[cxx, cxy], [cyx, cyy]] [x', y']``. Each coefficient is a parameter
    ``<name>.kxx`` etc. [N/m, N s/m].

    Examples
    --------
    >>> from twin.fem import Bearing
    >>> b = Bearing("UGB", 1, dict(kxx=1., kxy=2., kyx=3., kyy=4., cxx=0., cxy=0., cyx=0., cyy=0.))
    >>> [p.name for p in b.parameters()][:2]
    ['UGB.kxx', 'UGB.kxy']
    """

    name: str
    node: int
    coefficients: dict[str, float]

    def parameters(self) -> list[Parameter]:
        """The 8 coefficients as parameters."""
        dofs = node_dofs(self.node)[:2]
        out = []
        for key, (kind, row, col) in BEARING_COEFFICIENTS.items():
            unit = "N/m" if kind == "K" else "N s/m"
            what = "stiffness" if kind == "K" else "damping"
            out.append(
                Parameter(
                    f"{self.name}.{key}",
                    self.coefficients[key],
                    unit,
                    (_single_entry(kind, dofs, row, col),),
                    f"{self.name} bearing {what} {key}",
                    bounds=POSITIVE if row == col else UNBOUNDED,
                )
            )
        return out


@dataclass(frozen=True)
class ThrustBearing:
    """Tilt stiffness ``k_tilt`` [N m/rad] and damping ``c_tilt`` [N m s/rad] on alpha and beta.

    A thrust bearing carries the axial load; laterally it resists tilting of
    the thrust collar equally about x and y. Parameters ``<name>.k_tilt`` and
    ``<name>.c_tilt``.

    Examples
    --------
    >>> from twin.fem import ThrustBearing
    >>> [p.unit for p in ThrustBearing("thrust", 2, 5e9, 1e7).parameters()]
    ['N m/rad', 'N m s/rad']
    """

    name: str
    node: int
    k_tilt: float
    c_tilt: float

    def parameters(self) -> list[Parameter]:
        """Tilt stiffness and damping as parameters."""
        dofs = node_dofs(self.node)[2:]
        return [
            Parameter(
                f"{self.name}.k_tilt",
                self.k_tilt,
                "N m/rad",
                (Term("K", dofs, np.eye(2)),),
                f"{self.name} tilt stiffness",
                bounds=POSITIVE,
            ),
            Parameter(
                f"{self.name}.c_tilt",
                self.c_tilt,
                "N m s/rad",
                (Term("C", dofs, np.eye(2)),),
                f"{self.name} tilt damping",
                bounds=POSITIVE,
            ),
        ]
