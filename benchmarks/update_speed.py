"""Case B, 500 draws, one chain: time and ESS of the updater, beside emcee and NUTS on the same density.

The default sampler (``--method hmc``, twin.update's default: the errors-in-variables
marginal of the parameters, sampled by twin's HMC with its per-mode slice
step) is compared with the same HMC without that step and with two
general samplers on the same 46-dimensional log density: emcee (affine-
invariant ensemble, run for the same wall time) and, when nutpie is
installed, its NUTS (diagonal mass matrix adapted in 300 tuning steps). For
the Gibbs samplers (``--method gibbs`` with its options, ``--method paper``) emcee samples
the Gibbs sampler's own joint density (parameters, latent shapes and
perturbations, log residual variances). ESS is ArviZ's bulk ESS.

    python benchmarks/update_speed.py [--draws 500] [--seed 1] [--method hmc|gibbs|paper]
                                      [--pole-model linear|samples] [--noise-model full|diagonal] [--collapsed|--no-collapsed]

emcee and nutpie are optional (``pip install emcee nutpie``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import twin
from twin.tasks import one_blas_thread
from twin.update import marginal as marginal_model
from twin.update import sampler, synthesize_modes
from twin.update.chain import NOISE_MODELS, Prior, State
from twin.update.samplers import hmc
from twin.update.samplers.conditionals import initial_state, log_density, sweep
from twin.update.samplers.gibbs import GIBBS_POLE_MODELS, run_chain
from twin.update.posterior import _arviz
from twin.update.problem import build_problem, select_parameters


def _ess(az, x: np.ndarray, method: str = "bulk") -> np.ndarray:
    """Bulk (or tail) ESS of each column of draws ``x`` (chains, draws, k)."""
    return np.array([az.ess(x[..., k], method=method) for k in range(x.shape[-1])])


def _report(
    label: str, seconds: float, ess: np.ndarray, names: list[str], n_bearings: int, tail: np.ndarray | None = None
) -> None:
    line = (
        f"{label}: {seconds:.1f} s; bulk ESS of all {ess.size} parameters: median {np.median(ess):.0f}, "
        f"min {ess.min():.0f} ({names[int(np.argmin(ess))]}); of the bearings: median "
        f"{np.median(ess[:n_bearings]):.0f}, min {ess[:n_bearings].min():.0f}; min ESS/s {ess.min() / seconds:.1f}"
    )
    if tail is not None:  # the 5% and 95% quantiles' ESS: what the 90% intervals rest on
        line += (
            f"; tail ESS median {np.median(tail):.0f}, min {tail.min():.0f} ({names[int(np.argmin(tail))]}), "
            f"min tail ESS/s {tail.min() / seconds:.1f}"
        )
    print(line)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=500)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--method", choices=("hmc", "gibbs", "paper"), default="hmc")
    ap.add_argument("--noise-model", choices=NOISE_MODELS, default=None, help="--method gibbs")
    ap.add_argument("--collapsed", action=argparse.BooleanOptionalAction, default=None, help="--method gibbs")
    ap.add_argument("--pole-model", choices=GIBBS_POLE_MODELS, default=None, help="--method gibbs")
    args = ap.parse_args()
    given = {k: getattr(args, k) for k in ("noise_model", "collapsed", "pole_model") if getattr(args, k) is not None}
    chosen = sampler(args.method)
    options = chosen.options(given)  # the sampler's defaults where not given
    args.pole_model = chosen.pole_model(options)
    if args.pole_model != "marginal":  # a Gibbs sampler: its options as the Gibbs sampler's
        gibbs = chosen.gibbs_options(options)
        args.noise_model, args.collapsed = gibbs.noise_model, gibbs.collapsed
    az = _arviz()
    model = twin.load_model(twin.shipped_model("hydro_unit"))
    data = synthesize_modes(model, samples=100, seed=args.seed)
    params = select_parameters(model, "bearings")
    t0 = time.perf_counter()
    problem = build_problem(model, data, params, fsi=True, pole_model=args.pole_model)
    names = problem.parameter_labels
    Kg = problem.n_global
    if args.pole_model == "marginal":
        marg = marginal_model.marginal_problem(problem, data["pole"].values)
        setup = time.perf_counter() - t0
        t0 = time.perf_counter()
        chain = hmc.run_chain(marg, args.draws, rng=np.random.default_rng(args.seed))
        seconds = time.perf_counter() - t0
        x = np.concatenate([chain.t, chain.eta.reshape(args.draws, -1)], axis=1)
        _report(
            f"twin HMC on the marginal, Case B, 1 chain x {args.draws} draws (+{hmc.WARMUP} warm-up; "
            f"+ {setup:.1f} s setup), accepted {chain.accepted.mean():.0%}",
            seconds,
            _ess(az, x[None]),
            names,
            Kg,
            tail=_ess(az, x[None], "tail"),
        )
        t0 = time.perf_counter()
        plain = hmc.run_chain(marg, args.draws, rng=np.random.default_rng(args.seed), per_mode_slice=False)
        plain_s = time.perf_counter() - t0
        x_plain = np.concatenate([plain.t, plain.eta.reshape(args.draws, -1)], axis=1)
        _report(
            f"the same HMC without the per-mode slice step (its time {plain_s / seconds:.2f} of the default's), "
            f"accepted {plain.accepted.mean():.0%}",
            plain_s,
            _ess(az, x_plain[None]),
            names,
            Kg,
            tail=_ess(az, x_plain[None], "tail"),
        )
        _compare_marginal(az, marg, seconds, args, names, Kg, x)
        return
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    chain = run_chain(
        problem,
        args.draws,
        burn_in=20,
        rng=np.random.default_rng(args.seed),
        prior=Prior.flat(problem, noise_model=args.noise_model),
        collapsed=args.collapsed,
    )
    gibbs_s = time.perf_counter() - t0
    x = np.concatenate([chain.t, chain.eta.reshape(args.draws, -1)], axis=1)
    _report(
        f"Gibbs ({args.noise_model} noise, {args.pole_model} poles{', collapsed step' if args.collapsed else ''}), "
        f"Case B, 1 chain x {args.draws} draws (+20 burn-in; + {setup:.1f} s setup)",
        gibbs_s,
        _ess(az, x[None]),
        names,
        Kg,
    )
    if chain.accepted.any():
        print(f"collapsed step accepted in {chain.accepted.mean():.0%} of the sweeps")
    _emcee_gibbs(az, model, data, params, gibbs_s, args)


def _compare_marginal(az, marg, seconds: float, args, names: list[str], Kg: int, x_hmc: np.ndarray) -> None:
    """emcee and nutpie's NUTS on the marginal density the HMC chain sampled."""
    n = marg.size
    zero = np.zeros(n)
    mode, at = marginal_model.posterior_mode(marg, zero, zero)

    def logp(v: np.ndarray) -> float:
        try:
            return marginal_model.log_density(marg, v).log_p
        except np.linalg.LinAlgError:
            return -np.inf

    try:
        import emcee
    except ImportError:
        print("emcee is not installed (pip install emcee): no comparison")
    else:
        walkers = 2 * n + 2
        rng = np.random.default_rng(args.seed)
        cov = np.linalg.inv(at.precision)
        sampler = emcee.EnsembleSampler(walkers, n, logp)
        state = rng.multivariate_normal(mode, cov, size=walkers)  # started in the posterior (in its favour)
        t0, steps = time.perf_counter(), 0
        with_one_thread = one_blas_thread(sampler.run_mcmc)
        while time.perf_counter() - t0 < seconds:
            state = with_one_thread(state, 10, progress=False)
            steps += 10
        chains = np.swapaxes(sampler.get_chain(), 0, 1)  # (walkers, steps, n)
        ess = _ess(az, chains)  # counts walkers as chains: an upper bound this early
        _report(
            f"emcee on the same marginal ({walkers} walkers, {steps} steps in the same wall time; ESS counts "
            "walkers as chains)",
            time.perf_counter() - t0,
            ess,
            names,
            Kg,
        )
    try:
        import nutpie
        from nutpie.compiled_pyfunc import from_pyfunc
    except ImportError:
        print("nutpie is not installed (pip install nutpie): no NUTS comparison")
        return

    def make_logp():
        def f(v, **_):
            try:
                d = marginal_model.log_density(marg, np.asarray(v))
            except np.linalg.LinAlgError:
                return -np.inf, np.zeros(n)
            return d.log_p, d.gradient

        return f

    def make_expand(*_):
        return lambda v, **__: {"theta": np.asarray(v).copy()}

    compiled = from_pyfunc(
        n, make_logp, make_expand, [np.dtype("float64")], [(n,)], ["theta"], make_initial_point_fn=lambda _: mode.copy()
    )
    t0 = time.perf_counter()
    trace = one_blas_thread(nutpie.sample)(
        compiled, draws=args.draws, tune=300, chains=1, cores=1, seed=args.seed, progress_bar=False
    )
    nuts_s = time.perf_counter() - t0
    x = trace.posterior["theta"].values
    steps = float(trace.sample_stats["n_steps"].mean())
    _report(
        f"nutpie NUTS on the same marginal, 1 chain x {args.draws} draws (+300 tuning), {steps:.0f} gradient "
        "steps per draw",
        nuts_s,
        _ess(az, x),
        names,
        Kg,
    )
    ratio = x[0].std(axis=0) / x_hmc.std(axis=0)
    print(f"posterior std, NUTS / twin HMC: median {np.median(ratio):.2f}, range {ratio.min():.2f}-{ratio.max():.2f}")


def _emcee_gibbs(az, model, data, params, gibbs_s: float, args) -> None:
    """emcee on the paper's joint density (parameters, shapes, perturbations, log variances)."""
    try:
        import emcee
    except ImportError:
        print("emcee is not installed (pip install emcee): no comparison")
        return
    problem = build_problem(model, data, params, fsi=True)  # the paper's posterior
    start = initial_state(problem)
    for _ in range(50):  # start emcee where Gibbs is after burn-in (in its favour)
        sweep(problem, start, Prior.flat(problem), np.random.default_rng(0))
    I, Kg, Km = problem.n_modes, problem.n_global, problem.n_per_mode
    sizes = [Kg, I * Km, start.z.size, start.w.size]
    cut = np.cumsum(sizes)[:-1]

    def unpack(v):
        t, eta, z, logw = np.split(v, cut)
        return State(t, eta.reshape(I, Km), z.reshape(start.z.shape), np.exp(logw.reshape(start.w.shape)))

    def logp(v):
        s = unpack(v)
        return log_density(problem, s) + np.sum(np.log(s.w))  # Jacobian of w = exp(log w)

    x0 = np.concatenate([start.t, start.eta.ravel(), start.z.ravel(), np.log(start.w.ravel())])
    n_dim = x0.size
    walkers = 2 * n_dim + 2
    rng = np.random.default_rng(args.seed)
    p0 = x0 + 1e-6 * np.abs(x0 + 1e-3) * rng.standard_normal((walkers, n_dim))
    sampler = emcee.EnsembleSampler(walkers, n_dim, logp)
    t0 = time.perf_counter()
    state = p0
    steps = 0
    while time.perf_counter() - t0 < gibbs_s:
        state = sampler.run_mcmc(state, 1, progress=False)
        steps += 1
    emcee_s = time.perf_counter() - t0
    chains = sampler.get_chain()[:, :, :Kg]  # (steps, walkers, Kg)
    if steps < 4:
        print(
            f"emcee, same posterior ({n_dim} dimensions, {walkers} walkers): {steps} ensemble step(s) in "
            f"{emcee_s:.1f} s; too few for any ESS estimate (no effective sample in the Gibbs run's wall time)"
        )
        return
    ess_e = np.array([az.ess(np.swapaxes(chains[:, :, k], 0, 1), method="bulk") for k in range(Kg)])
    print(
        f"emcee, same posterior ({n_dim} dimensions, {walkers} walkers), {emcee_s:.1f} s: {steps} steps; "
        f"bulk ESS of the bearings: median {np.median(ess_e):.1f}, min {ess_e.min():.1f}; "
        f"median ESS/s {np.median(ess_e) / emcee_s:.2f}"
    )
    print("(emcee's ESS counts walkers as chains; after so few steps from a tight ball it is an upper bound)")


if __name__ == "__main__":
    main()
