"""Stage 3: automated modal extraction (covariance-driven SSI) from signals to pole and shape samples."""

from twin.extract.core import extract
from twin.extract.modesfile import read_modes, write_modes
from twin.extract.stabilisation import Criteria

__all__ = ["Criteria", "extract", "read_modes", "write_modes"]
