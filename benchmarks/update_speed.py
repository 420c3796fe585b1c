"""Case B, 500 draws, one chain: time of the APerCEM Gibbs sampler, and ESS/s against emcee on the same posterior.

The posterior is the sampler's own joint density (shared and per-mode parameters,
latent shapes and perturbations, log residual variances), written as one flat
vector for emcee (affine-invariant ensemble, the generic sampler), run for the
same wall time. ESS is ArviZ's bulk ESS of the 16 bearing coefficients.

    python benchmarks/update_speed.py [--draws 500] [--seed 1] [--paper | [--noise-model full|diagonal]
                                      [--collapsed|--no-collapsed] [--pole-model linear|samples]]

The options time the Gibbs sampler in another configuration (default: the
calibrated one, twin.update.CALIBRATED, as update() uses; --paper: the
paper's); emcee (``pip install emcee``) always samples the paper's posterior.
It also prints the bulk ESS of the slowest parameters of the Gibbs chain.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import twin
from twin.update import CALIBRATED, PAPER, synthesize_modes
from twin.update.gibbs import NOISE_MODELS, Prior, State, initial_state, log_density, run_chain, sweep
from twin.update.poles import POLE_MODELS
from twin.update.posterior import _arviz
from twin.update.problem import build_problem, select_parameters


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=500)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--noise-model", choices=NOISE_MODELS, default=CALIBRATED["noise_model"])
    ap.add_argument("--collapsed", action=argparse.BooleanOptionalAction, default=CALIBRATED["collapsed"])
    ap.add_argument("--pole-model", choices=POLE_MODELS, default=CALIBRATED["pole_model"])
    ap.add_argument("--paper", action="store_true", help="the paper's sampler (twin.update.PAPER)")
    args = ap.parse_args()
    if args.paper:
        vars(args).update(PAPER)
    az = _arviz()
    model = twin.load_model(twin.shipped_model("hydro_unit"))
    data = synthesize_modes(model, samples=100, seed=args.seed)
    t0 = time.perf_counter()
    params = select_parameters(model, "bearings")
    problem = build_problem(model, data, params, fsi=True, pole_model=args.pole_model)
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    chain = run_chain(problem, args.draws, burn_in=20, rng=np.random.default_rng(args.seed),
                      prior=Prior.flat(problem, noise_model=args.noise_model), collapsed=args.collapsed)
    gibbs_s = time.perf_counter() - t0
    print(f"configuration: noise model {args.noise_model}, pole model {args.pole_model}"
          f"{', collapsed step' if args.collapsed else ''}")
    if (args.noise_model, args.collapsed, args.pole_model) != ("diagonal", False, "samples"):
        problem = build_problem(model, data, params, fsi=True)  # emcee on the paper's posterior
    ess_g = np.array([az.ess(chain.t[None, :, k], method="bulk") for k in range(problem.n_global)])
    print(f"Gibbs, Case B (46 parameters), 1 chain x {args.draws} draws (+20 burn-in): {gibbs_s:.1f} s "
          f"(+ {setup:.1f} s setup); bulk ESS of the bearings: median {np.median(ess_g):.0f}, min {ess_g.min():.0f}; "
          f"median ESS/s {np.median(ess_g) / gibbs_s:.1f}")  # fmt: skip
    x = np.concatenate([chain.t, chain.eta.reshape(args.draws, -1)], axis=1)
    ess_all = np.array([az.ess(x[None, :, k], method="bulk") for k in range(x.shape[1])])
    names = problem.parameter_labels
    print("slowest parameters (bulk ESS): " + ", ".join(f"{names[k]} {ess_all[k]:.0f}" for k in np.argsort(ess_all)[:6]))
    if chain.accepted.any():
        print(f"collapsed step accepted in {chain.accepted.mean():.0%} of the sweeps")

    try:
        import emcee
    except ImportError:
        print("emcee is not installed (pip install emcee): no comparison")
        return

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
        print(f"emcee, same posterior ({n_dim} dimensions, {walkers} walkers): {steps} ensemble step(s) in "
              f"{emcee_s:.1f} s; too few for any ESS estimate (no effective sample in the Gibbs run's wall time)")
        return
    ess_e = np.array([az.ess(np.swapaxes(chains[:, :, k], 0, 1), method="bulk") for k in range(Kg)])
    print(f"emcee, same posterior ({n_dim} dimensions, {walkers} walkers), {emcee_s:.1f} s: {steps} steps; "
          f"bulk ESS of the bearings: median {np.median(ess_e):.1f}, min {ess_e.min():.1f}; "
          f"median ESS/s {np.median(ess_e) / emcee_s:.2f}")  # fmt: skip
    print("(emcee's ESS counts walkers as chains; after so few steps from a tight ball it is an upper bound)")


if __name__ == "__main__":
    main()
