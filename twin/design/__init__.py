"""Before any measurement: what a sensor layout and a record can determine, and where to add a sensor.

* :func:`observability`: per target mode, the response against the noise per
  channel and the expected standard errors of its frequency and damping;
* :func:`identifiability`: the expected posterior std of parameters from the
  observable modes' poles and shapes (Fisher information);
* :class:`Excitation`: the turbulence, noise, record length and sampling rate judged.
"""

from twin.design.identify import identifiability
from twin.design.observe import Excitation, observability

__all__ = ["Excitation", "identifiability", "observability"]
