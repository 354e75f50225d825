"""A bit fingerprint of the Riccati and observer outputs, for changes that must not move any figure (mend20).

One line per case: its label, ``ok`` / ``DE`` (DesignError) / ``EXC``, and a sha256 of the bytes of every array
returned and the repr of every other figure and message (long double arrays as their exact pair hi + lo of doubles:
``np.longdouble``'s storage has padding bytes that differ between processes). Run it on both trees in separate
processes and compare the outputs byte for byte, e.g. with tB exported by ``git archive REV | tar -x -C /tmp/base``:

    PYTHONPATH=/tmp/base OPENBLAS_NUM_THREADS=1 python benchmarks/riccati_fingerprint.py filters > before.txt
    PYTHONPATH=$PWD      OPENBLAS_NUM_THREADS=1 python benchmarks/riccati_fingerprint.py filters > after.txt

Parts (default all): ``filters`` — filter_riccati (P, L, Kf, Σ, accuracy), riccati_existence, observable_order,
boundary_gap, spectral_riccati on the factored control form, newton_refined / closed_loop_correction / _condition /
forward_refined from the design's P perturbed by 1e-6, on tests/test_kalman_riccati._problem and
tests/test_riccati_forward.deflated_problem seeds 0–19 × trials 0–2 and the scaled family
(tests/test_riccati_failure_messages.scaled_random_case 0–89); ``observers`` — observer_gain (given and default
poles), observable_order, balanced_pair on scaled_random_case 0–299; ``designs`` — kalman, luenberger, Beard–Jones
(two fault sets), UIO (filter matrices and every info entry) and postconditions._plant_reading on
tests/judge_models.ill_scaled_model 0–23; ``plant`` — _plant_reading alone.

SB03MD's separation estimate (``sep`` and the ``floor`` from it, in _condition's and forward_refined's figures) is
hashed to 9 digits: it differs in its last 1–3 ulps between two processes of the same code (tB ac7dadb too: 34 of
209 _condition lines differed between two runs) — the solver's result depends on the arrays' memory alignment.

28 Nov, mend20 (one DiagonalBalancing; check_detectable folded; riccati_existence; _plant_reading's wasted solve),
against tB ac7dadb: filters 1,886 lines, observers 1,200, designs 144 (incl. _plant_reading) — all identical.
"""
import hashlib
import sys
import warnings
from pathlib import Path

import numpy as np

import fmu_fdi  # (the tree whose package PYTHONPATH imports: its tests' problem generators)

ROOT = Path(fmu_fdi.__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
warnings.simplefilter("ignore")

from fmu_fdi.errors import DesignError  # noqa: E402
from fmu_fdi.design.observers import _observer  # noqa: E402
from fmu_fdi.design.toolkit import riccati_newton as rn, approximate  # noqa: E402
from fmu_fdi.design.toolkit import postconditions as pc  # noqa: E402
from test_kalman_riccati import _problem  # noqa: E402
from test_riccati_forward import deflated_problem  # noqa: E402
from test_riccati_failure_messages import scaled_random_case  # noqa: E402
from judge_models import ill_scaled_model  # noqa: E402

EXIST = getattr(_observer, "riccati_existence", None) or getattr(_observer, "_existence")  # before mend20: private
DETECT = _observer.observable_order


def h(*objs) -> str:
    m = hashlib.sha256()
    for o in objs:
        if isinstance(o, np.ndarray) and o.dtype in (np.longdouble, np.clongdouble):
            # long double's storage has padding bytes of no value: hash the exact pair hi + lo of doubles instead
            parts = (o.real, o.imag) if o.dtype == np.clongdouble else (o,)
            m.update(repr((o.dtype, o.shape)).encode())
            for x in parts:
                hi = x.astype(float)
                m.update(hi.tobytes())
                m.update((x - hi).astype(float).tobytes())
        elif isinstance(o, np.ndarray):
            m.update(repr((o.dtype, o.shape)).encode())
            m.update(np.ascontiguousarray(o).tobytes())
        elif isinstance(o, dict):
            for k in sorted(o):
                m.update(k.encode())
                # SB03MD's separation estimate (and the floor from it) varies in its last 1-3 ulps between processes
                # of the same code (tB as well): read to 9 digits, every other figure to the bit
                m.update((f"{o[k]:.9e}" if k in ("sep", "floor") else h(o[k])).encode())
        elif isinstance(o, (list, tuple)):
            for x in o:
                m.update(h(x).encode())
        else:
            m.update(repr(o).encode())
    return m.hexdigest()[:16]


def run(label, fn):
    try:
        out = fn()
        st = "ok"
    except DesignError as exc:
        out, st = ("DesignError", str(exc)), "DE"
    except Exception as exc:  # noqa: BLE001
        out, st = ("EXC", type(exc).__name__, str(exc)), "EXC"
    print(label, st, h(out), flush=True)


def filt(A, C, Qx, R, dt):
    S = np.zeros((A.shape[0], C.shape[0]))
    f = _observer.filter_riccati(A, C, Qx, R, S, dt)
    return [f.P, f.L, f.Kf, f.Sigma, f.accuracy]


def family(name, problem, seeds, trials=3):
    for seed in range(seeds):
        for trial in range(trials):
            A, C, Qx, R, dt = problem(seed, trial)[:5]
            S = np.zeros((A.shape[0], C.shape[0]))
            run(f"filter {name} {seed}/{trial}", lambda: filt(A, C, Qx, R, dt))
            run(f"exist {name} {seed}/{trial}", lambda: EXIST(A, C, Qx, R, S, dt))
            run(f"detect {name} {seed}/{trial}", lambda: DETECT(A, C, dt))
            run(f"gap {name} {seed}/{trial}", lambda: rn.boundary_gap(A.T.copy(), C.T.copy(), Qx, R, S, dt))
            # spectral_riccati on the factored control form
            lam, V = np.linalg.eigh(Qx)
            G = V * np.sqrt(np.clip(lam, 0, None))
            n, p = A.shape[0], R.shape[0]
            H = np.vstack([G.T, np.zeros((p, n))])
            D = np.vstack([np.zeros((n, p)), np.sqrt(R)])
            fig = {}
            run(f"spectral {name} {seed}/{trial}",
                lambda: [approximate.spectral_riccati(A.T.copy(), C.T.copy(), H, D, dt, figures=fig), fig])
            # newton / correction / condition from a perturbed scipy-ish start: the design's own P perturbed
            try:
                P = filt(A, C, Qx, R, dt)[0]
            except DesignError:
                continue
            rng = np.random.default_rng(seed * 7 + trial)
            E = rng.standard_normal(P.shape) * 1e-6 * np.abs(P).max()
            P1 = P + (E + E.T) / 2
            run(f"newton {name} {seed}/{trial}",
                lambda: rn.newton_refined(A.T.copy(), C.T.copy(), Qx, R, S, P1, dt, 1e-12))
            run(f"correction {name} {seed}/{trial}",
                lambda: rn.closed_loop_correction(A.T.copy(), C.T.copy(), Qx, R, S, P1, dt))
            run(f"condition {name} {seed}/{trial}",
                lambda: rn._condition(A.T.copy(), C.T.copy(), Qx, R, S, P1, dt, P1 - P))
            ff = {}
            run(f"forward {name} {seed}/{trial}",
                lambda: [rn.forward_refined(A.T.copy(), C.T.copy(), Qx, R, S, P1, dt, figures=ff), ff])


def gain_fp(g):
    return [g.L, g.poles, g.fixed, g.method]


def observers(count):
    for seed in range(count):
        A, C, Qx, R, dt, *_ = scaled_random_case(seed)
        n = A.shape[0]
        poles = (np.linspace(0.2, 0.6, n) if dt else -np.linspace(1.0, 3.0, n)).astype(complex)
        run(f"gain {seed}", lambda: gain_fp(_observer.observer_gain(A, C, poles, dt)))
        run(f"gaindef {seed}", lambda: gain_fp(_observer.observer_gain(A, C, None, dt)))
        run(f"order {seed}", lambda: _observer.observable_order(A, C, dt))
        run(f"pair {seed}", lambda: (lambda b: [getattr(b[0], "t", b[0]), b[1]])(_observer.balanced_pair(A, C)))


def designs(count):
    from fmu_fdi.design.observers.kalman_filter import kalman
    from fmu_fdi.design.observers.output_observer import luenberger
    from fmu_fdi.design.observers.beard_jones import fault_detection_filter
    from fmu_fdi.design.observers.uio import unknown_input_observer

    def gen_fp(g):
        Q = g.Q
        return [Q.A, Q.B, Q.C, Q.D, repr(sorted((k, repr(v)) for k, v in g.info.items()))]

    for seed in range(count):
        m = ill_scaled_model(seed)
        nw = m.nw if hasattr(m, "nw") else m.Bw.shape[1]
        run(f"kalman {seed}", lambda: gen_fp(kalman(m, np.eye(nw) if nw else None, np.eye(m.ny) * 1e-2)))
        run(f"luenberger {seed}", lambda: gen_fp(luenberger(m)))
        run(f"beard {seed}", lambda: gen_fp(fault_detection_filter(m, faults=["fa1", "fa2"])))
        run(f"beard1 {seed}", lambda: gen_fp(fault_detection_filter(m, faults=["fa1"])))
        run(f"uio {seed}", lambda: gen_fp(unknown_input_observer(m)))
        Geb = pc.plant_realisation(m.augmented())
        w = np.logspace(-3, 3, 200)
        lam = np.exp(1j * w * m.dt) if m.dt else 1j * w
        run(f"plant_reading {seed}", lambda: list(pc._plant_reading(Geb, lam)))


def plant(count):
    for seed in range(count):
        m = ill_scaled_model(seed)
        Geb = pc.plant_realisation(m.augmented())
        w = np.logspace(-3, 3, 200)
        lam = np.exp(1j * w * m.dt) if m.dt else 1j * w
        run(f"plant_reading {seed}", lambda: list(pc._plant_reading(Geb, lam)))


if __name__ == "__main__":
    part = sys.argv[1] if len(sys.argv) > 1 else "all"
    if part in ("all", "filters"):
        family("full", _problem, 20)
        family("deflated", deflated_problem, 20)
        family("scaled", lambda s, t: scaled_random_case(3 * s + t), 30)
    if part in ("all", "observers"):
        observers(300)
    if part in ("all", "designs"):
        designs(24)
    if part == "plant":
        plant(24)
