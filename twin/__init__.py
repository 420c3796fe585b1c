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
   effect, add it, update, keep the error history (``Twin``); over months of
   records, :mod:`twin.track` detects, names and follows a change.

:mod:`twin.harness` runs the loop on scenarios with a hidden truth (``twin demo``,
``twin sweep``); :mod:`twin.report` holds the figures and pages both show.

Examples
--------
>>> import twin
>>> ds = twin.modal(twin.load_model(twin.shipped_model("hydro_unit")), n_modes=3)
>>> [str(w) for w in ds.whirl.values]
['forward', 'forward', 'mixed']
"""

__version__ = "0.1.0"

import importlib  # noqa: E402

from twin.errors import ModelError, ModelFileError, TwinError  # noqa: E402

#: The package's names and the modules they come from, imported on first use (PEP 562): ``import twin`` stays
#: quick, so the ``twin`` command answers ``--help`` and argument errors at once.
_LAZY = {
    "RotorModel": "twin.fem",
    "load_model": "twin.fem",
    "shipped_model": "twin.fem",
    "campbell": "twin.modes",
    "mac": "twin.modes",
    "modal": "twin.modes",
    "pair_modes": "twin.modes",
}

__all__ = [
    "ModelError",
    "ModelFileError",
    "RotorModel",
    "TwinError",
    "__version__",
    "campbell",
    "load_model",
    "mac",
    "modal",
    "pair_modes",
    "shipped_model",
]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'twin' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
