"""Coverage of the ``data:`` threshold's estimators: does each keep its stated confidence?

A ``data:RATE`` threshold (fmu_fdi/evaluation/gaussfit.log_threshold) claims: with probability
γ = 0.95 over the fault-free log it was computed from, the threshold lies at or above the true
``1 − RATE`` quantile of the evaluation J. Measured here, per residual model, evaluation, log
length and rate, for each estimator the ``data:`` threshold can use:

- ``empirical``: the distribution-free order statistic of the thinned evaluation,
- ``gpd``: the peaks-over-threshold (generalised Pareto) tail fit of the thinned evaluation,
- ``gaussian``: the Gaussian fit of the residual's autocovariance (exact quadratic-form quantile),

as the coverage — the share of independent logs whose threshold ≥ the true quantile — with its
Clopper–Pearson 95 % interval (a method keeps its confidence when the interval's upper end is
≥ 0.95), and the median threshold / true quantile (the cost of the confidence). Logs on which a
method refuses (too few effective samples) are counted apart.

Residual models (scalar, unit variance, stationary Gaussian): white; AR(1) with pole 0.9 and
0.99; a 2nd-order resonant one (poles 0.9·e^{±0.5i}). True quantiles: the evaluation of a
Gaussian sequence is a quadratic form of it, so for ``rms:N`` the quantile is Imhof's exact one
under the *true* autocovariance (from the impulse response), checked against a seeded Monte
Carlo run (printed: MC/exact); for ``norm`` it is ``σ z_{RATE/2}``; for ``peak:N`` a Monte Carlo
quantile of 10⁷ samples (printed with its order-statistic 95 % interval).

Usage: ``nice python benchmarks/threshold_coverage.py [--logs 40] [--quick] [--methods gpd,gaussian]``
(``--quick``: AR(1) models, rms:20, rate 1e-3 only).
"""
from __future__ import annotations

import argparse
import math
import time
import warnings

import numpy as np
from scipy import stats
from scipy.signal import lfilter

from fmu_fdi.evaluation import datadriven
from fmu_fdi.evaluation.datadriven import ShortLogError, data_driven_threshold
from fmu_fdi.evaluation.gaussfit import gaussian_threshold
from fmu_fdi.evaluation.quadform import imhof_quantile

CONFIDENCE = 0.95
#: name → (numerator, denominator) of the shaping filter of unit white noise
MODELS = {
    "white": ([1.0], [1.0]),
    "ar1-0.9": ([1.0], [1.0, -0.9]),
    "ar1-0.99": ([1.0], [1.0, -0.99]),
    "ar2-res": ([1.0], [1.0, -2 * 0.9 * math.cos(0.5), 0.81]),
}
EVALUATIONS = {"rms": {"kind": "rms", "window": 20}, "norm": {"kind": "norm"}, "peak": {"kind": "peak", "window": 20}}


def impulse(model, n=40_000):
    b, a = MODELS[model]
    return lfilter(b, a, np.r_[1.0, np.zeros(n - 1)])


def true_acf(model, lags):
    """γ(k) = Σ_i h_i h_{i+k} of the unit-variance-normalised model (k = 0..lags−1)."""
    h = impulse(model)
    g = np.array([h[:h.size - k] @ h[k:] for k in range(lags)])
    return g / g[0]


def simulate(model, n, rng):
    """A stationary record of n samples (burn-in 20 time constants of the slowest pole, at least 2000)."""
    b, a = MODELS[model]
    h = impulse(model)
    scale = 1.0 / math.sqrt(h @ h)
    burn = 2000 if model != "ar1-0.99" else 5000
    return scale * lfilter(b, a, rng.standard_normal(n + burn))[burn:]


def evaluate(r, spec):
    """J of a scalar record, computed here (cumulative sums / a running max), not with the runtime."""
    kind = spec["kind"]
    if kind == "norm":
        return np.abs(r)
    N = spec["window"]
    if kind == "rms":
        c = np.cumsum(np.r_[0.0, r * r])
        return np.sqrt((c[N:] - c[:-N]) / N)  # full windows only
    if kind == "peak":
        return np.lib.stride_tricks.sliding_window_view(np.abs(r), N).max(axis=1)  # max over r(k−N+1..k)
    raise ValueError(kind)


def true_quantile(model, ev, rate, mc_rng):
    """(quantile, note) — see the module docstring."""
    spec = EVALUATIONS[ev]
    if ev == "norm":
        return float(stats.norm.isf(rate / 2)), "exact"
    if ev == "rms":
        N = spec["window"]
        g = true_acf(model, N)
        S = g[np.abs(np.arange(N)[:, None] - np.arange(N)[None, :])] / N
        q = math.sqrt(imhof_quantile(rate, np.linalg.eigvalsh(S)))
        J = evaluate(simulate(model, 4_000_000, mc_rng), spec)
        return q, f"exact (Imhof, true ACF); MC 4e6 / exact = {np.quantile(J, 1 - rate) / q:.4f}"
    J = evaluate(simulate(model, 10_000_000, mc_rng), spec)
    m = J.size
    lo, hi = (int(stats.binom.ppf(p, m, 1 - rate)) for p in (0.025, 0.975))
    Js = np.partition(J, [lo, hi, int((1 - rate) * m)])
    return float(Js[int((1 - rate) * m)]), f"MC 1e7, order-statistic 95 % interval [{Js[lo]:.4g}, {Js[hi]:.4g}] (serially correlated: wider)"


def clopper_pearson(k, n, level=0.95):
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else stats.beta.ppf(a, k, n - k + 1)
    hi = 1.0 if k == n else stats.beta.ppf(1 - a, k + 1, n - k)
    return lo, hi


def estimate(method, r, J, spec, rate):
    N = spec.get("window", 1)
    if method == "gaussian":
        return gaussian_threshold(r, spec, rate, CONFIDENCE, skip=N).value
    kw = {"tail_power": datadriven.tail_power_for(spec["kind"])} if hasattr(datadriven, "tail_power_for") else {}
    return data_driven_threshold(J, rate, CONFIDENCE, method=method, **kw).value  # as log_threshold calls it


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=int, default=40, help="independent logs per cell")
    ap.add_argument("--quick", action="store_true", help="AR(1) models, rms:20, rate 1e-3")
    ap.add_argument("--methods", default="empirical,gpd,gaussian")
    ap.add_argument("--lengths", default="3000,12000")
    ap.add_argument("--rates", default="1e-3,1e-4")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--evals", default="rms,norm,peak", help="norm and peak run on white and ar1-0.9 only")
    args = ap.parse_args(argv)
    methods = args.methods.split(",")
    lengths = [int(x) for x in args.lengths.split(",")]
    rates = [float(x) for x in args.rates.split(",")]
    models = args.models.split(",")
    evals = args.evals.split(",")
    if args.quick:
        models, evals, rates = ["ar1-0.9", "ar1-0.99"], ["rms"], [1e-3]
    cells = [(m, e) for m in models for e in evals if e == "rms" or m in ("white", "ar1-0.9")]
    print(f"coverage of data: thresholds at confidence {CONFIDENCE}: {args.logs} logs per cell, seeded\n")
    print(f"{'model':9} {'eval':6} {'rate':>6} {'T':>6} {'method':9} {'cover':>7} {'CP 95 %':>13} {'refused':>7} "
          f"{'med thr/q':>9} {'s/fit':>6}")
    t_all = time.perf_counter()
    warnings.simplefilter("ignore", RuntimeWarning)
    for model, ev in cells:
        spec = EVALUATIONS[ev]
        for rate in rates:
            q, note = true_quantile(model, ev, rate, np.random.default_rng(12345))
            print(f"# {model} {ev} rate {rate:g}: true quantile {q:.5g} ({note})")
            for T in lengths:
                logs = [simulate(model, T, np.random.default_rng([T, i, sum(map(ord, model))])) for i in range(args.logs)]
                for method in methods:
                    vals, refused, t0 = [], 0, time.perf_counter()
                    for r in logs:
                        J = evaluate(r, spec)
                        try:
                            vals.append(estimate(method, r, J, spec, rate))
                        except (ShortLogError, ValueError):
                            refused += 1
                    dt = (time.perf_counter() - t0) / max(len(logs), 1)
                    if not vals:
                        print(f"{model:9} {ev:6} {rate:6g} {T:6d} {method:9} {'-':>7} {'':>13} {refused:7d}")
                        continue
                    k, n = int(np.sum(np.asarray(vals) >= q)), len(vals)
                    lo, hi = clopper_pearson(k, n)
                    flag = "" if hi >= CONFIDENCE else "  < nominal"
                    print(f"{model:9} {ev:6} {rate:6g} {T:6d} {method:9} {k:3d}/{n:<3d} [{lo:.3f},{hi:.3f}] {refused:7d} "
                          f"{np.median(vals) / q:9.3f} {dt:6.2f}{flag}", flush=True)
    print(f"\ntotal {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
