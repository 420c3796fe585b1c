"""twin: a digital twin of rotating machines whose dynamics the surrounding water changes.

The loop, one stage per subpackage, each a function with one file format on
each side:

* :mod:`twin.fem`: rotor FEM read from a TOML model file (:func:`load_model`);
* :mod:`twin.modes`: complex modal analysis (:func:`modal`), MAC, pairing, Campbell diagram.

Examples
--------
>>> import twin
>>> ds = twin.modal(twin.load_model("models/hydro_unit.toml"), n_modes=3)
>>> [str(w) for w in ds.whirl.values]
['forward', 'forward', 'mixed']
"""

__version__ = "0.1.0"

from twin.errors import ModelError, ModelFileError, TwinError  # noqa: E402
from twin.fem import RotorModel, load_model  # noqa: E402
from twin.modes import campbell, mac, modal, pair_modes  # noqa: E402

__all__ = [
    "ModelError", "ModelFileError", "RotorModel", "TwinError", "__version__",
    "campbell", "load_model", "mac", "modal", "pair_modes",
]  # fmt: skip
