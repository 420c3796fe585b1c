"""Stage 5: the twin loop — compare a model with measured modes, diagnose the missing effect.

* :func:`compare`: per-mode and per-sensor errors and the overall error ``E``;
* :func:`diagnose`: where the model fails and which library effect is missing;
* :func:`candidates`, :func:`add_effects`: the candidate effects;
* :class:`Twin`: model + measured modes + the history of the error after each step.

The measured modes it reads are :func:`twin.modes.measured_modes`'s.
"""

from twin.errors import CompareError
from twin.loop.candidates import add_effects, candidates
from twin.loop.compare import compare
from twin.loop.diagnose import diagnose
from twin.loop.twin import Twin

__all__ = ["CompareError", "Twin", "add_effects", "compare", "candidates", "diagnose"]
