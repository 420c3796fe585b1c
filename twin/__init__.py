"""twin: a digital twin of rotating machines whose dynamics the surrounding water changes.

The loop, one stage per subpackage, each a function with one file format on
each side (``twin --help`` for the same from the command line):

1. :mod:`twin.fem`: the rotor FEM read from a TOML model file
   (:func:`load_model`; the shipped ones through :func:`shipped_model`), its
   uncertain parameters and effects; :mod:`twin.modes` for its complex modes
   (:func:`modal`), MAC, pairing and Campbell diagram;
2. :mod:`twin.fmu`: the model as an FMU (``export_fmu``) simulated through
   FMPy into proximeter signals (``simulate``, ``signals.nc``);
3. :mod:`twin.extract`: stochastic subspace identification, signals to
   samples of poles and partial mode shapes (``extract``, ``modes.nc``);
4. :mod:`twin.update`: the APerCEM Gibbs updater, modes to a posterior in the
   ArviZ layout (``update``, ``posterior.nc``);
5. :mod:`twin.loop`: compare model and measurements, diagnose the missing
   effect, add it, update, keep the error history (``Twin``, ``demo``).

Examples
--------
>>> import twin
>>> ds = twin.modal(twin.load_model(twin.shipped_model("hydro_unit")), n_modes=3)
>>> [str(w) for w in ds.whirl.values]
['forward', 'forward', 'mixed']
"""

__version__ = "0.1.0"

from twin.errors import ModelError, ModelFileError, TwinError  # noqa: E402
from twin.fem import RotorModel, load_model, shipped_model  # noqa: E402
from twin.modes import campbell, mac, modal, pair_modes  # noqa: E402

__all__ = [
    "ModelError", "ModelFileError", "RotorModel", "TwinError", "__version__",
    "campbell", "load_model", "mac", "modal", "pair_modes", "shipped_model",
]  # fmt: skip
