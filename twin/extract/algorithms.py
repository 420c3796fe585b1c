"""The identification algorithms the extraction can read a record's covariances with: one interface.

Both work on the record's output covariances (:func:`twin.extract.ssi.block_covariances`, so the
jackknife of :mod:`twin.extract.samples` serves both) and answer, model order by model order, with
continuous-time poles and output shapes; the stabilisation diagram, the clustering, the jackknife
and the harmonic tests after them are the same.

- ``"ssi"`` (the default): covariance-driven stochastic subspace identification
  (:func:`twin.extract.ssi.realise`), model orders 2, 4, ... ``max_order``. Lightly damped modes,
  slow ones among them, on the lags the block rows span.
- ``"plscf"``: the poly-reference least-squares complex frequency-domain fit of the half spectra
  over the band (:func:`twin.extract.plscf.matrix_fraction`), model orders ``m, 2m, ...`` for ``m``
  channels. Heavily damped and overlapping modes, whose covariances die out within the first
  lags (``docs/decisions/extraction-plscf.md`` says when to use which).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from twin.defaults import ALGORITHMS
from twin.extract.plscf import matrix_fraction
from twin.extract.ssi import realise

#: pLSCF fits the band of interest widened by this factor (``fmin / m`` to ``m fmax``): the Pelton unit's
#: 94.8 Hz mode, damped 11%, has a half-power band of +-10.7 Hz, and fitted up to fmax = 100 Hz its damping
#: came out 5.7-8.1% on five records; up to 125 Hz 7.3-8.5%. The modes kept are those within the band.
BAND_MARGIN = 1.25
#: What each is called in files and messages.
ALGORITHM_NAMES = {"ssi": "covariance-driven SSI", "plscf": "pLSCF"}


class Fit(Protocol):
    """What an algorithm's fit of one covariance sequence answers (:class:`twin.extract.ssi.Realisation`,
    :class:`twin.extract.plscf.MatrixFraction`)."""

    @property
    def n_channels(self) -> int: ...

    @property
    def max_order(self) -> int: ...

    @property
    def orders(self) -> np.ndarray: ...

    def modes(self, order: int) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class Algorithm:
    """An identification algorithm and the band [Hz] it reads.

    Examples
    --------
    >>> from twin.extract.ssi import block_covariances
    >>> y = np.random.default_rng(0).standard_normal((4000, 2))
    >>> R = block_covariances(y, 21).covariance()
    >>> Algorithm("ssi").fit(R, 10, 8, 20.0).orders.tolist(), Algorithm("plscf", (0.0, 8.0)).fit(R, 10, 8, 20.0).orders.tolist()
    ([2, 4, 6, 8], [2, 4, 6, 8])
    """

    name: str = ALGORITHMS[0]
    band_hz: tuple[float, float] = (0.0, float("inf"))

    def __post_init__(self) -> None:
        if self.name not in ALGORITHMS:
            raise ValueError(f"the identification algorithm must be one of {', '.join(ALGORITHMS)}, got {self.name!r}")

    @property
    def starts_near(self) -> bool:
        """Whether a fit gains from ``near`` (:meth:`fit`): SSI's iterative singular vectors."""
        return self.name == "ssi"

    def fit(
        self, R: np.ndarray, block_rows: int, max_order: int, fs_hz: float, first_lag: int = 1, near: Fit | None = None
    ) -> Fit:
        """The algorithm's fit of the covariances ``R`` (lags ``0..2 block_rows + first_lag - 1``).

        pLSCF fits the band widened by :data:`BAND_MARGIN` on either side (within the Nyquist
        frequency), so that a heavily damped mode near an edge has its half-power band in the fit.
        ``near`` is a fit of nearly the same covariances (the full record's, for a jackknife sample):
        SSI starts its singular vectors from it (:func:`twin.extract.ssi.leading_singular`).
        """
        if self.name == "ssi":
            start = getattr(near, "basis", None)
            return realise(R, block_rows, max_order, fs_hz, first_lag=first_lag, start=start)
        lo, hi = self.band_hz
        band = (lo / BAND_MARGIN, min(hi * BAND_MARGIN, fs_hz / 2))
        return matrix_fraction(R, max_order, fs_hz, band, first_lag=first_lag)


SSI = Algorithm()
