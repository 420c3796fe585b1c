"""Stage 4: APerCEM Bayesian updating (DESIGN section 5): modes.nc + model -> posterior.nc.

* :func:`update`: the posterior of shared parameters and per-mode FSI, by HMC
  on their marginal with the shapes and pole deviations integrated out
  (:data:`CALIBRATED`, the default; :mod:`twin.update.marginal`) or by the
  Gibbs sampler (:data:`PAPER`, the reference paper's);
* :func:`synthesize_modes`: paper-style synthetic modal data (its Figure 2);
* :func:`apply_posterior`: the model with the posterior MAP or mean applied;
* :func:`summary`, :func:`read_posterior`: the posterior's table and file.
"""

from twin.update.core import CALIBRATED, PAPER, update
from twin.update.posterior import apply_posterior, read_posterior, summary
from twin.update.problem import UpdateError
from twin.update.synthetic import synthesize_modes

__all__ = ["CALIBRATED", "PAPER", "UpdateError", "apply_posterior", "read_posterior", "summary", "synthesize_modes", "update"]
