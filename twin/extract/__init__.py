"""Stage 3: automated modal extraction (covariance-driven SSI) from signals to pole and shape samples.

The ``modes.nc`` file it writes is read and written by :func:`twin.modes.read_modes` and
:func:`twin.modes.write_modes`.
"""

from twin.extract.core import extract
from twin.extract.options import ExtractOptions
from twin.extract.stabilisation import Criteria

__all__ = ["Criteria", "ExtractOptions", "extract"]
