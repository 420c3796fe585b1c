"""Before any measurement: what a sensor layout and a record can determine, and where to add a sensor.

* :func:`observability`: per target mode, the response against the noise per
  channel and the expected standard errors of its frequency and damping;
* :func:`identifiability`: the expected posterior std of parameters from the
  observable modes' poles and shapes (Fisher information);
* :func:`design_sensors`: where to add proximeter pairs (greedy on observability,
  identifiability and a D-optimal criterion), and :func:`write_layout` to write the
  model file with them;
* :class:`Excitation`: the turbulence, noise, record length and sampling rate judged.
"""

from twin.design.identify import identifiability
from twin.design.observe import observability
from twin.design.sensors import design_sensors, write_layout
from twin.design.spectrum import Excitation

__all__ = ["Excitation", "design_sensors", "identifiability", "observability", "write_layout"]
