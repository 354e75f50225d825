"""A decoupled block's reading served from a reading of more columns (postconditions._decoupled_values, judge18).

A bank's check reads each member's filter on the member's own grid again, but on other columns than the member did
(u, d and each excluded fault alone, where the member's row model read u and [d, excluded faults]). The judge keeps
each reading per column and serves a request whose columns it has read on the same filter, plant realisation and
points, refining where the request's own blocks need it. Shown here on exact audit seed 17's bank (6 rows, every
row with one excluded fault):

- one realisation per plant, whatever the order of its inputs (the bank's model and a member's row model);
- a served reading equals a fresh one of the same request (no new plain reading computed): the same points refined
  and, at each point, the values within the bound both readings carry — each is within ``3N·u_x·||err||`` (refined
  point) or ``3N·u·||err||`` (plain point) of the stored filter's exact value (postconditions._decoupled_reading's
  derivation), so they are within the sum of the two bounds of each other (the sensitivities, reported beside the
  figures, within 1e-6 relative; the bounds, which measure each reading's own residual since judge23, within
  5.3e-3 here);
- the bank's figures (info['postconditions']) with its readings served equal those of a check on an empty store;
  the bank's own check computes no new plain reading.
"""
import numpy as np
import pytest

from fmu_fdi import freqresp
from fmu_fdi.design import structured_bank
from fmu_fdi.design.problems import banks
from fmu_fdi.design.problems.achievable import achievable_structure
from fmu_fdi.design.toolkit import postconditions as pc
from fmu_fdi.linalg import EPS
from test_synthesis_random import random_case

SEED = 17


@pytest.fixture(scope="module")
def bank17():
    """Seed 17's bank on every row achievable_structure lists, with the plain readings its own check computed."""
    model = random_case(SEED)
    S = np.asarray(achievable_structure(model), int).reshape(-1, len(model.faults))
    check, plain, counted = banks.check_generator, pc._plain_values, {"bank": 0}
    phase = ["rows"]

    def counting_plain(*a):
        counted[phase[0]] = counted.get(phase[0], 0) + 1
        return plain(*a)

    def marked_check(gen, **kw):
        phase[0] = "bank"
        try:
            return check(gen, **kw)
        finally:
            phase[0] = "rows"

    freqresp.clear_caches()
    pc._UD_CACHE.clear()
    banks.check_generator, pc._plain_values = marked_check, counting_plain
    try:
        bank = structured_bank(model, S)
    finally:
        banks.check_generator, pc._plain_values = check, plain
    return model, S, bank, counted


def test_one_plant_realisation_whatever_the_order_of_its_inputs(bank17):
    model = bank17[0]
    row = model.with_disturbances([model.faults[2].name])  # u, [d, fa1], w, the other faults
    full, mine = pc.plant_realisation(model.augmented()), pc.plant_realisation(row.augmented())
    key = lambda G, c: (G.B[:, c].tobytes(), G.D[:, c].tobytes())  # noqa: E731
    assert np.array_equal(full.A, mine.A) and np.array_equal(full.C, mine.C)
    assert sorted(key(full, c) for c in range(full.m)) == sorted(key(mine, c) for c in range(mine.m))
    # a diagonal similarity x = T x_bal by powers of 2 of the plant as given: exactly the same data
    Ge = model.augmented()
    t = np.ones(Ge.n)
    for i in range(Ge.n):
        r, c = np.flatnonzero(Ge.C[:, i]), np.flatnonzero(Ge.B[i])
        t[i] = full.C[r[0], i] / Ge.C[r[0], i] if r.size else Ge.B[i, c[0]] / full.B[i, c[0]] if c.size else 1.0
    assert np.all(np.log2(t) == np.round(np.log2(t)))
    assert np.array_equal(full.A, Ge.A / t[:, None] * t[None, :])
    assert np.array_equal(full.B, Ge.B / t[:, None]) and np.array_equal(full.C, Ge.C * t[None, :])


def _requests(model, row):
    """The member's request (u, [d, excluded faults]), a required fault's columns, and the bank's kinds of request
    on the member's columns."""
    sl = model.group_slices()
    fsl = sl["f"]
    fcols = [np.arange(fsl.start, fsl.stop)[f.columns] for f in model.faults]
    u, d = np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)
    excl = [fcols[j] for j in np.flatnonzero(np.asarray(row) == 0)]
    member = [u, np.concatenate([d] + excl)]
    reqs = [[u], [d], [u, d], *([c] for c in excl), [u, d, *excl], [np.concatenate([d] + excl), u]]
    required = fcols[int(np.flatnonzero(np.asarray(row) == 1)[0])]
    return member, required, [[r for r in q if r.size] for q in reqs if any(r.size for r in q)]


def _read(Qi, Geb, lam, req):
    cols = np.concatenate(req)
    at = np.cumsum([0] + [r.size for r in req])
    blocks = [np.arange(at[k], at[k + 1]) for k in range(len(req))]
    return pc._decoupled_values(Qi, Geb[:, cols], lam, blocks, with_refined=True), blocks


def test_served_reading_equals_a_fresh_one(bank17, monkeypatch):
    model, S, bank, _ = bank17
    if pc.EXT_UNIT >= EPS / 2:
        pytest.skip("numpy's longdouble is double here: nothing is refined")
    Geb = pc.plant_realisation(model.augmented())
    plain, computed = pc._plain_values, [0]

    def counting(*a):
        computed[0] += 1
        return plain(*a)

    monkeypatch.setattr(pc, "_plain_values", counting)
    kinds = {"served plain where the first reading refined": 0, "refined anew": 0}
    for g, row in enumerate(S):
        Qi = pc.row_system(bank.Q, bank.groups[g])
        lam = pc.judge_points(model, Qi, [list(range(Qi.p))])[0]
        N = max(Qi.n, Geb.n, 1)
        member, required, requests = _requests(model, row)
        # first read with the member's partition, or as one block with a required fault (a high top: few points)
        for first in (member, [np.concatenate(member + [required])]):
            pc._UD_CACHE.clear()
            _read(Qi, Geb, lam, first)
            first_refined = np.any(next(iter(pc._UD_CACHE.values())).refined, axis=1)
            for req in requests:
                before = computed[0]
                (sv, se, ss, sneed), blocks = _read(Qi, Geb, lam, req)
                assert computed[0] == before, "a request on columns already read computed a new plain reading"
                kept = pc._UD_CACHE.copy()
                pc._UD_CACHE.clear()
                (fv, fe, fs, need), _ = _read(Qi, Geb, lam, req)
                pc._UD_CACHE.clear()
                pc._UD_CACHE.update(kept)
                # the points each reading refined (its repeated refinement test, judge19), not a mask re-derived
                # from the final values
                assert np.array_equal(need, sneed)
                kinds["served plain where the first reading refined"] += int(np.sum(first_refined & ~need))
                kinds["refined anew"] += int(np.sum(need & ~first_refined))
                # sens: a first-order figure (reported beside the figures, deciding nothing) read from the computed
                # |Z|, whose rounding differs between the two readings; 1e-6 relative keeps it the same to far more
                # digits than it is meaningful (measured here: ≤ 8e-12). err is not compared so: since judge23 it
                # adds each reading's *measured* residual |W r̂| (postconditions._plain_values), a rounding-sized
                # quantity of that reading's own solve (here the two differ by ≤ 5.3e-3 of err); each is a bound
                # of its own reading's error (tests/test_judge_plain_bound.py), which is what is checked below
                na, nb = np.linalg.norm(ss, axis=(1, 2)), np.linalg.norm(fs, axis=(1, 2))
                assert np.all(np.abs(na - nb) <= 1e-6 * np.maximum(na, nb))
                # values: each within its own bound of the exact value (3N·u_x·||err|| refined, 3N·u·||err|| plain),
                # so within the sum of the two bounds of each other
                unit = 3 * N * np.where(need, pc.EXT_UNIT, EPS / 2)
                e = (np.linalg.norm(fe, axis=(1, 2)) + np.linalg.norm(se, axis=(1, 2))) * unit
                assert np.all(np.linalg.norm(sv - fv, axis=(1, 2)) <= e)
    # both ways a request's refined points differ from the first reading's occur on this bank
    assert all(v > 0 for v in kinds.values()), kinds


def test_bank_figures_served_equal_a_check_on_an_empty_store(bank17):
    model, S, bank, counted = bank17
    assert counted["bank"] == 0, "the bank's check computed plain readings its members had read"
    names = [f.name for f in model.faults]
    freqresp.clear_caches()
    pc._UD_CACHE.clear()
    fresh = pc.check_generator(bank, decouple=("u", "d"), structure=S, faults=names, raise_error=False)
    served = bank.info["postconditions"]
    assert not fresh.get("failures") and not served.get("failures")
    assert np.array_equal(np.asarray(served["structure_matrix"]), np.asarray(fresh["structure_matrix"]))
    for x, e in (("decoupling_rows", "decoupling_row_errors"), ("structure_leak", "structure_leak_error")):
        a, b = np.asarray(served[x], float), np.asarray(fresh[x], float)
        assert np.all(np.abs(a - b) <= 2 * np.maximum(np.asarray(served[e]), np.asarray(fresh[e])))
    for x in ("fault_gain", "scales", "filter_peak_gain", "fault_visibility"):
        assert np.array_equal(np.asarray(served[x], float), np.asarray(fresh[x], float)), x
