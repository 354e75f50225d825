"""Time of the fault-to-noise gaps of an afdi_bank read two ways in the same run.

Baseline: the previous ``analysis.fault_noise_gap`` (kept below as :func:`hstack_gap`): each block
of the internal form realised on its own (``internal_form()``: ``R[:, d]``, ``R[:, w]``, ``R[:, f]``
minimal each) and the noise block ``[Rf_i (S_i = 0)  Rd_i  Rw_i]`` built by putting those
realisations side by side (block-diagonal states) before one minimal realisation and AB13DD.
New: :func:`fmu_fdi.analysis.fault_noise_gap`, every norm on a column slice of the one minimal
realisation of ``R = Q·[Gu Gd Gw Gf; I 0 0 0]``. Both are read per member (``banks.row_gaps``'s
way: each row group on its own member). Prints the times, their ratio, the largest state order
each way hands to AB13DD for a noise block, and the largest relative difference of the gaps.

The design itself (afdi_bank, whose ``info['gaps']`` are ``banks.row_gaps``) is also timed both
ways: once with the baseline patched in for ``analysis.fault_noise_gap``, once as shipped.
With ``--stacked`` the whole bank's rows are read both ways too: the baseline is the previous stacked reading
(:func:`stacked_rows_gap`: rows of the bank's one minimal realisation ``bank._R``, which keep the other
members' states), the new one ``fault_noise_gap(bank, S)``, which reads each group on the states its rows
observe (``ResidualGenerator.group_internal_form``) and must equal ``bank.info['gaps']`` bit for bit.

Run: python benchmarks/gap_speed.py [--stacked] [SEED …]   (default seeds 1 2)

Measured (27 Nov, 2 shared cores, one run each): seed 68 (n 21) afdi_bank 15.4 s -> 5.2 s (3.0), per-member
gaps 17.08 s -> 1.06 s (16.1; noise block 240 states -> member R 60), stacked rows 74.8 s -> 7.3 s (10.3;
571 -> 143 states); seed 78 (n 25) afdi_bank 14.3 s -> 2.8 s (5.1), per-member gaps 12.44 s -> 0.34 s
(37.1; 213 -> 71 states), with --stacked in another run its stacked rows 116.3 s -> 45.2 s (2.6; 482 ->
162 states: the rows keep the other members' states); seeds 1, 2 gaps ratio 1.8, 2.1 (hundredths of a second). Gaps agree to 3e-13.
Stacked, 27 Nov (tenth session, load ~11, fresh banks for both readings): seed 68 rows of the stacked R 12.12 s
(143 states) -> each group on its own states 0.26 s (60 states), ratio 46.1, gaps agree to 7.2e-11; seed 78
11.74 s (162 states) -> 0.41 s (71 states), ratio 28.6, 5.1e-11; the new gaps equal the design's row_gaps bit
for bit. (A first run that reused the design's cached member forms read 144.0 s -> 3.50 s on seed 78: the
load varies these by 10x; the ratios above are of one run each.)
The rows are those ``approximate_random_judged.py --gap-time`` picks (the audit's check_case).
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_approximate_random import noisy_case  # noqa: E402

from fmu_fdi.analysis import _slice_norm, fault_noise_gap  # noqa: E402
from fmu_fdi.design import afdi_bank  # noqa: E402
from fmu_fdi.design.problems.achievable import achievable_structure  # noqa: E402
from fmu_fdi.design.problems.banks import ResidualBank  # noqa: E402
from fmu_fdi.lti import hstack  # noqa: E402


def hstack_gap(gen, S) -> tuple[np.ndarray, int]:
    """The baseline per-row gaps (previous fault_noise_gap) and the largest noise-block order it reduced."""
    R = gen.internal_form()
    m = gen.model
    blocks = [np.arange(m.nf)[f.columns] for f in m.faults]
    S = np.asarray(S).astype(bool)
    gaps, order = [], 0
    for i, g in enumerate(gen.groups):
        Rf_i = R["f"][g, :]
        beta = min((Rf_i[:, blocks[j]].minreal().hinfnorm()[0] for j in range(len(blocks)) if S[i, j]),
                   default=0.0)
        others = [Rf_i[:, blocks[j]] for j in range(len(blocks)) if not S[i, j]]
        others += [X[g, :] for X in (R["d"], R["w"]) if X.m]
        others = [s for s in others if s.m]
        noise = 0.0
        if others:
            N = hstack(others)
            order = max(order, N.n)
            noise = N.minreal().hinfnorm()[0]
        gaps.append(float("inf") if noise <= np.sqrt(np.finfo(float).eps) else beta / noise)
    return np.array(gaps), order


def stacked_rows_gap(gen, S) -> np.ndarray:
    """The previous stacked reading of ``fault_noise_gap(gen, S)``: every row group on column slices of the
    rows of the bank's one minimal realisation ``gen._R`` (which keep the other members' states)."""
    R, m = gen._R, gen.model
    sl = m.group_slices()
    fcols = np.arange(sl["f"].start, sl["f"].stop)
    blocks = [fcols[f.columns] for f in m.faults]
    dw = np.r_[np.arange(sl["d"].start, sl["d"].stop), np.arange(sl["w"].start, sl["w"].stop)].astype(int)
    S = np.asarray(S).astype(bool)
    gaps = []
    for i, g in enumerate(gen.groups):
        rows = np.asarray(g, int)
        beta = min((_slice_norm(R, rows, blocks[j]) for j in range(len(blocks)) if S[i, j]), default=0.0)
        others = [blocks[j] for j in range(len(blocks)) if not S[i, j]]
        noise = _slice_norm(R, rows, np.concatenate(others + [dw]).astype(int))
        gaps.append(float("inf") if noise <= np.sqrt(np.finfo(float).eps) else beta / noise)
    return np.array(gaps)


def rel_diff(new, old) -> tuple[float, bool]:
    """Largest relative difference of the finite gaps of ``old``, and whether ``new`` is ∞ where ``old`` is."""
    new, old = np.asarray(new, float), np.asarray(old, float)
    fin = np.isfinite(old)
    return (float(np.max(np.abs(new[fin] - old[fin]) / np.abs(old[fin]), initial=0.0)),
            bool(np.all(np.isinf(new[~fin]))))


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def _rows(model, seed):
    listed = np.asarray(achievable_structure(model), int).reshape(-1, len(model.faults))
    rng = np.random.default_rng(seed)
    return listed if len(listed) <= 3 else listed[np.sort(rng.choice(len(listed), 3, False))]


def _baseline_gap(gen, S=None):
    return hstack_gap(gen, S)[0]


def main(seeds, stacked: bool = False) -> None:
    import fmu_fdi.analysis as analysis

    print(f"{'seed':>4s} {'n':>3s} {'design old s':>12s} {'design s':>8s} {'ratio':>6s} {'hstack s':>9s} "
          f"{'slice s':>8s} {'ratio':>6s} {'hstack n':>8s} {'R n':>4s} {'max rel diff':>12s}")
    afdi_bank(noisy_case(1), _rows(noisy_case(1), 1))  # warm-up (imports, caches): the first design paid them
    for seed in seeds:
        model = noisy_case(seed)
        rows = _rows(model, seed)
        new_fn = analysis.fault_noise_gap
        analysis.fault_noise_gap = _baseline_gap  # banks.row_gaps imports it at call time
        try:
            bank_old, t_design_old = _timed(lambda: afdi_bank(model, rows))
        finally:
            analysis.fault_noise_gap = new_fn
        bank, t_design = _timed(lambda: afdi_bank(model, rows))
        d_design, same_design = rel_diff(bank.info["gaps"], bank_old.info["gaps"])
        S_all = np.zeros((len(bank.members), len(model.faults)), dtype=int)
        for j, nm in enumerate(bank.info["faults"]):
            S_all[:, model.fault_index(nm)] = rows[:, j]
        ones = [ResidualBank([mb], bank.method) for mb in bank.members]
        for one in ones:  # the internal form, common to both readings, realised before timing
            one._R
        old, t_old = _timed(lambda: [hstack_gap(one, S_all[i:i + 1]) for i, one in enumerate(ones)])
        new, t_new = _timed(lambda: [fault_noise_gap(one, S_all[i:i + 1])[0] for i, one in enumerate(ones)])
        diff, same_inf = rel_diff(new, [o[0][0] for o in old])
        print(f"{seed:4d} {model.n:3d} {t_design_old:12.1f} {t_design:8.1f} {t_design_old / t_design:6.1f} "
              f"{t_old:9.2f} {t_new:8.2f} {t_old / t_new:6.1f} "
              f"{max(o[1] for o in old):8d} {max(one._R.n for one in ones):4d} {max(diff, d_design):12.1e}"
              f"{'' if same_inf and same_design else '  (an infinite gap differs)'}", flush=True)
        if stacked:  # the whole bank's rows (its internal form carries every member's states)
            # fresh banks of the same members, so that neither reading finds the design's cached forms: the old one
            # builds the stacked bank._R, the new one each group's own Q_i·Ge
            old_bank, new_bank = (ResidualBank(list(bank.members), bank.method, dict(bank.info)) for _ in range(2))
            rows_s, t_rows = _timed(lambda: stacked_rows_gap(old_bank, S_all))
            new_s, t_new = _timed(lambda: fault_noise_gap(new_bank, S_all))
            diff2, same_inf2 = rel_diff(new_s, rows_s)
            print(f"     stacked bank: rows of the stacked R {t_rows:.2f} s "
                  f"(R {bank._R.n} states), each group on its own states {t_new:.2f} s "
                  f"(R_i {max(bank.group_internal_form(i).n for i in range(len(bank.groups)))} states); ratio "
                  f"{t_rows / t_new:.1f}; max rel diff {diff2:.1e}"
                  f"{'' if same_inf2 else '  (an infinite gap differs)'}", flush=True)
            assert np.array_equal(new_s, bank.info["gaps"]), "group_internal_form is not row_gaps' member form"

if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:] if a != "--stacked"] or [1, 2], "--stacked" in sys.argv)
