"""The ``posterior.nc`` file (ArviZ layout), its diagnostics and point estimates.

Groups, readable by ``arviz.from_netcdf`` and
``xarray.open_datatree``:

* ``posterior``: ``theta`` (chain, draw, parameter) in SI units with the
  model's names (``UGB.kxx``); with per-mode FSI ``added_mass`` [kg] and
  ``added_damping`` [N s/m] (chain, draw, mode); the observed shape
  ``shape_real``/``shape_imag`` (chain, draw, mode, channel);
* ``sample_stats``: ``lp`` (log joint density, up to a constant),
  ``noise_variance`` (mean of Δ_i over the rows, relative units) and
  ``accepted``; from the HMC of the marginal model also ArviZ's
  ``acceptance_rate``, ``step_size`` and ``n_steps`` (chain, draw);
* ``observed_data``: the pole and shape samples updated on;
* ``constant_data``: nominal values and scales of the parameters.

R-hat and ESS are ArviZ's (rank-normalised split R-hat, bulk and tail ESS,
Vehtari et al. 2021): the reference implementation our users check against.
"""

from __future__ import annotations

import json
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import xarray as xr
from scipy.stats import gaussian_kde

from twin.errors import TwinError, TwinWarning
from twin.modes.modesfile import split_complex
from twin.fem.effects import FluidAddedMassPerMode
from twin.fem.model import RotorModel
from twin.netcdf import write_netcdf

#: Names of per-mode parameters (``FSI.added_mass_3``).
PER_MODE = re.compile(r"^FSI\.added_(mass|damping)_\d+$")
#: Groups every posterior file has.
GROUPS = ("posterior", "sample_stats", "observed_data", "constant_data")
#: R-hat above which a warning is given.
RHAT_LIMIT = 1.01
#: Grid points of the kernel density estimate that locates the posterior mode.
MAP_GRID = 512


def _arviz():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz

    return arviz


def parameter_draws(posterior: xr.Dataset) -> xr.DataArray:
    """All scalar parameters as one (chain, draw, parameter) array in SI units.

    The FSI parameters are named ``FSI.added_mass_<mode>``, ``FSI.added_damping_<mode>``.
    """
    parts = []
    if "theta" in posterior:
        parts.append(posterior["theta"])
    for kind in ("added_mass", "added_damping"):
        if kind in posterior:
            da = posterior[kind]
            labels = [f"FSI.{kind}_{int(m)}" for m in da["mode"].values]
            parts.append(da.rename(mode="parameter").assign_coords(parameter=labels))
    if not parts:
        raise TwinError("the posterior holds no parameter (no 'theta', 'added_mass' or 'added_damping')")
    return xr.concat(
        [p.drop_vars([c for c in p.coords if c not in ("chain", "draw", "parameter")]) for p in parts], dim="parameter"
    )


def posterior_mode(draws: np.ndarray) -> float:
    """Mode of a 1-D sample, from a Gaussian kernel density estimate (the mean for a constant sample).

    Examples
    --------
    >>> x = np.random.default_rng(0).gamma(3.0, 1.0, 20000)
    >>> abs(posterior_mode(x) - 2.0) < 0.15   # the gamma(3, 1) mode is 2
    True
    """
    draws = np.asarray(draws, dtype=float).ravel()
    if np.ptp(draws) == 0:
        return float(draws.mean())
    grid = np.linspace(draws.min(), draws.max(), MAP_GRID)
    return float(grid[np.argmax(gaussian_kde(draws)(grid))])


def summary(posterior: xr.Dataset, truth: Mapping[str, float] | None = None) -> xr.Dataset:
    """Per-parameter summary: mean, MAP, std, 5% and 95% quantiles, R-hat, bulk and tail ESS.

    With ``truth`` (SI values by parameter name) also the relative error of
    the MAP and the z-score ``(mean - truth) / std``.
    """
    az = _arviz()
    draws = parameter_draws(posterior)
    ds = draws.to_dataset(name="x")
    flat = draws.stack(sample=("chain", "draw"))
    out = xr.Dataset(
        {
            "mean": flat.mean("sample"),
            "std": flat.std("sample", ddof=1),
            "map": ("parameter", list(estimates(posterior, "map").values())),
            "q05": flat.quantile(0.05, "sample").drop_vars("quantile"),
            "q95": flat.quantile(0.95, "sample").drop_vars("quantile"),
        }
    )
    if draws.sizes["chain"] >= 2 and draws.sizes["draw"] >= 4:
        out["r_hat"] = az.rhat(ds)["x"]
    if draws.sizes["draw"] >= 4:
        out["ess_bulk"] = az.ess(ds, method="bulk")["x"]
        out["ess_tail"] = az.ess(ds, method="tail")["x"]
    if truth is not None:
        t = np.array([truth.get(str(p), np.nan) for p in draws["parameter"].values])
        out["truth"] = ("parameter", t)
        with np.errstate(divide="ignore", invalid="ignore"):
            out["map_error"] = ("parameter", out["map"].values / t - 1)
            out["z_score"] = ("parameter", (out["mean"].values - t) / out["std"].values)
    return out


def write_posterior(tree: xr.DataTree, path: str | Path) -> Path:
    """Write a posterior DataTree to NetCDF groups (atomic)."""
    return write_netcdf(tree, path)


def read_posterior(path: str | Path) -> xr.DataTree:
    """Read ``posterior.nc`` into memory; a clear error when it is not one."""
    path = Path(path)
    if not path.is_file():
        raise TwinError(f"{path}: no such posterior file")
    try:
        with xr.open_datatree(path) as tree:
            tree = tree.load()
    except (OSError, ValueError) as exc:
        raise TwinError(f"{path}: not a readable NetCDF posterior file ({exc})") from None
    missing = [g for g in GROUPS if g not in tree.children]
    if missing:
        raise TwinError(f"{path}: not a posterior file: no group {', '.join(missing)}")
    return tree


def is_laplace(posterior: xr.DataTree | xr.Dataset) -> bool:
    """Whether a posterior is the Laplace fit's Gaussian (:func:`laplace_tree`), not a sampler's draws."""
    group = posterior["posterior"] if isinstance(posterior, xr.DataTree) else posterior
    return "laplace_map" in group.attrs


def estimates(posterior: xr.Dataset, estimate: str = "map") -> dict[str, float]:
    """Point estimate of every parameter (``"map"``: marginal posterior mode, or ``"mean"``), SI.

    A Laplace posterior (:func:`laplace_tree`) carries its exact MAP in the attr ``laplace_map``.
    """
    if estimate not in ("map", "mean"):
        raise TwinError(f"estimate must be 'map' or 'mean', got {estimate!r}")
    if estimate == "map" and "laplace_map" in posterior.attrs:
        return {k: float(v) for k, v in json.loads(posterior.attrs["laplace_map"]).items()}
    draws = parameter_draws(posterior)
    flat = draws.stack(sample=("chain", "draw"))
    if estimate == "mean":
        return {str(p): float(v) for p, v in zip(draws["parameter"].values, flat.mean("sample").values)}
    return {str(p): posterior_mode(flat.sel(parameter=p).values) for p in draws["parameter"].values}


def apply_posterior(model: RotorModel, posterior: xr.Dataset | xr.DataTree, estimate: str = "map") -> RotorModel:
    """The model with the posterior's point estimates applied (the twin after an update).

    Shared parameters (``theta``, including a mode-independent ``FSI.added_mass``)
    replace the model's values; per-mode FSI becomes (or replaces) the
    model's ``fsi_per_mode`` effect, value ``i`` for target mode ``i``.
    Target modes the posterior does not cover keep the model's per-mode
    values (zero when it has none). An estimate outside its parameter's
    physical bounds (a flat-prior posterior of a parameter the data hardly
    determine) is put on the bound, with a warning naming it: the model
    stays physical and solvable. An estimate on a bound (a fit the bound
    stopped) is used, with a warning naming it.

    Examples
    --------
    >>> import xarray as xr
    >>> from twin.update import apply_posterior
    >>> import numpy as np, xarray as xr
    >>> m = hydro_unit
    >>> post = xr.Dataset({"theta": (("chain", "draw", "parameter"), np.full((1, 3, 1), 7e8))},
    ...                   coords={"parameter": ["UGB.kxx"]})
    >>> apply_posterior(m, post, "mean").parameter("UGB.kxx").nominal
    700000000.0
    """
    if isinstance(posterior, xr.DataTree):
        posterior = posterior["posterior"].to_dataset()
    values = estimates(posterior, estimate)
    modes = posterior["mode"].values.astype(int) if "added_mass" in posterior else np.zeros(0, int)
    per_mode = {f"FSI.{k}_{m}" for k in ("added_mass", "added_damping") for m in modes}
    shared = {k: v for k, v in values.items() if k not in per_mode}
    shared = {k: _within_bounds(k, v, model.parameter(k).bounds) for k, v in shared.items()}
    updated = model.with_values(shared) if shared else model
    if not len(modes):
        return updated
    if modes.min() < 1 or len(set(modes)) != len(modes):
        raise TwinError(f"per-mode FSI needs distinct target modes numbered from 1; the posterior has {list(modes)}")
    old = updated.per_mode_effect
    n = max(int(modes.max()), len(old.added_mass) if old is not None else 0)
    mass, damping = np.zeros(n), np.zeros(n)
    if old is not None:
        mass[: len(old.added_mass)], damping[: len(old.added_damping)] = old.added_mass, old.added_damping
    for m in modes:
        mass[m - 1] = _within_bounds(f"FSI.added_mass_{m}", values[f"FSI.added_mass_{m}"], (0.0, np.inf))
        damping[m - 1] = _within_bounds(f"FSI.added_damping_{m}", values[f"FSI.added_damping_{m}"], (0.0, np.inf))
    effect = FluidAddedMassPerMode(tuple(map(float, mass)), tuple(map(float, damping)))
    return updated.without_per_mode_effect().with_effects(effect)


def _within_bounds(name: str, value: float, bounds: tuple[float, float]) -> float:
    low, high = bounds
    if value in (low, high):  # a fit pushed there: the data ask for more than physics allows
        warnings.warn(
            f"the posterior estimate of {name} is on its physical bound, {value:.4g} "
            f"(bounds [{low:.4g}, {high:.4g}]): the data push it beyond, which usually means an effect "
            "the model lacks (twin diagnose) rather than that value",
            TwinWarning,
            stacklevel=3,
        )
        return value
    if low <= value <= high:
        return value
    bound = low if value < low else high
    warnings.warn(
        f"the posterior estimate of {name}, {value:.4g}, lies outside its physical bounds "
        f"[{low:.4g}, {high:.4g}] (the data hardly determine it): {bound:.4g} is used",
        TwinWarning,
        stacklevel=3,
    )
    return float(bound)


def observed_data(modes: xr.Dataset) -> xr.Dataset:
    """The posterior's ``observed_data`` group: the pole and shape samples, complex parts stored apart.

    Only the ``mode``, ``sample`` and ``channel`` coordinates are kept (a modes file's others, such as the
    channels' nodes or ``pole_order_cov``'s parts, describe variables the group does not hold).

    Examples
    --------
    >>> ds = xr.Dataset({"pole": (("mode", "sample"), [[-1 + 9j, -1 + 11j]]), "shape": (("mode", "sample",
    ...                  "channel"), np.ones((1, 2, 1)) + 0j), "n": ("part", [1, 2])}, coords={"part": [0, 1]})
    >>> sorted(observed_data(ds).data_vars), list(observed_data(ds).coords)
    (['pole_imag', 'pole_real', 'shape_imag', 'shape_real'], [])
    """
    sub = modes[["pole", "shape"]]
    return split_complex(sub.drop_vars([c for c in sub.coords if c not in ("mode", "sample", "channel")]))


def parameter_coords(names: Sequence[str], units: Sequence[str] | None = None) -> dict:
    """The coordinates of a posterior's ``parameter`` dimension: the names and, where known, each one's SI unit
    (``theta`` holds parameters of many units: a stiffness in N/m beside a damping in N s/m).

    Examples
    --------
    >>> parameter_coords(["UGB.stiffness_change", "UGB.damping_change"], ["N/m", "N s/m"])["units"]
    ('parameter', ['N/m', 'N s/m'])
    """
    coords: dict = {"parameter": list(names)}
    if units is not None:
        if len(units) != len(names):
            raise ValueError(f"{len(units)} units for {len(names)} parameters")
        coords["units"] = ("parameter", [str(u) for u in units])
    return coords


def laplace_tree(
    post: xr.Dataset, modes: xr.Dataset, attrs: dict, draws: int = 1000, seed: int | None = 0
) -> xr.DataTree:
    """A Laplace posterior (:func:`twin.update.laplace.laplace_update`) in the ``posterior.nc`` layout.

    ``posterior`` holds ``draws`` draws of the Gaussian (MAP, covariance)
    kept inside the parameters' physical bounds (rejection), in one chain;
    per-mode FSI parameters (``FSI.added_mass_<i>``) go to ``added_mass`` and
    ``added_damping`` over ``mode``, the others to ``theta``. The exact MAP
    is the posterior group's attr ``laplace_map`` (used by :func:`estimates`).
    """
    names = [str(n) for n in post["parameter"].values]
    mean, cov = post["map"].values, post["covariance"].values
    low, high = post["low"].values, post["high"].values
    rng = np.random.default_rng(seed)
    kept, tries = [], 0
    while sum(len(k) for k in kept) < draws and tries < 50:
        x = rng.multivariate_normal(mean, cov, size=2 * draws, method="eigh")
        kept.append(x[np.all((x >= low) & (x <= high), axis=1)])
        tries += 1
    x = np.concatenate(kept)[:draws] if kept else np.zeros((0, len(names)))
    if len(x) < draws:  # the bounds cut away almost all of the Gaussian: the draws sit on them
        x = np.clip(rng.multivariate_normal(mean, cov, size=draws, method="eigh"), low, high)
    coords = {"chain": [0], "draw": np.arange(draws)}
    per_mode = [n for n in names if PER_MODE.match(n)]
    shared = [n for n in names if n not in per_mode]
    out = xr.Dataset(coords=coords, attrs={"laplace_map": json.dumps(dict(zip(names, map(float, mean))))})
    if shared:
        idx = [names.index(n) for n in shared]
        units = [str(u) for u in post["unit"].values[idx]] if "unit" in post else None
        out["theta"] = xr.DataArray(
            x[None, :, idx],
            dims=("chain", "draw", "parameter"),
            coords=parameter_coords(shared, units),
            attrs={"long_name": "updated model parameters (SI units of each parameter: coordinate units)"},
        )
    labels = sorted({int(n.rsplit("_", 1)[1]) for n in per_mode})
    for kind, unit in (("added_mass", "kg"), ("added_damping", "N s/m")):
        cols = [names.index(f"FSI.{kind}_{m}") for m in labels if f"FSI.{kind}_{m}" in names]
        if cols and len(cols) == len(labels):
            out[kind] = xr.DataArray(
                x[None, :, cols],
                dims=("chain", "draw", "mode"),
                coords={"mode": labels},
                attrs={"units": unit, "long_name": f"per-mode FSI {kind.replace('_', ' ')}"},
            )
    stats = xr.Dataset(
        {"lp": (("chain", "draw"), np.zeros((1, draws)), {"long_name": "not recorded (Laplace)"})}, coords=coords
    )
    observed = observed_data(modes)
    constant = post[["map", "std", "prior_scale", "low", "high"]].drop_vars("unit", errors="ignore")
    return xr.DataTree.from_dict(
        {
            "/": xr.Dataset(attrs=attrs),
            "posterior": out,
            "sample_stats": stats,
            "observed_data": observed,
            "constant_data": constant,
        }
    )


def diagnostics_json(table: xr.Dataset) -> str:
    """R-hat and ESS per parameter as JSON (for file attrs)."""
    keys = [k for k in ("r_hat", "ess_bulk", "ess_tail") if k in table]
    return json.dumps({str(p): {k: float(table[k].sel(parameter=p)) for k in keys} for p in table["parameter"].values})


def stretch(draws: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """Draws (..., K) stretched about their mean by ``factors`` (K,): the calibration's widening of a posterior.

    Examples
    --------
    >>> d = np.array([[0.0, 1.0], [2.0, 3.0]])
    >>> stretch(d, np.array([2.0, 1.0]))
    array([[-1.,  1.],
           [ 3.,  3.]])
    """
    axes = tuple(range(draws.ndim - 1))
    mean = draws.mean(axis=axes)
    return mean + factors * (draws - mean)
