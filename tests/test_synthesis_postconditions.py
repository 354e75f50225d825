"""Post-conditions of the synthesis functions (issue 13): a design returns a filter that
keeps its contract or raises a DesignError naming the failed condition.

Contract figures are judged independently (tests/synthesis_models.contract: frequency
responses of Q·Ge only). Tolerance 1e-6: a relative leak of an exact design is rounding,
~n·cond·eps ≲ 1e-9 on these models; the broken designs of the old code leaked 1e-4…1.
"""
import numpy as np
import pytest

import published as pub
from fmu_fdi import DesignError, leakage, nullspace_design, structure_matrix, structured_bank
from fmu_fdi.design.toolkit._basis import PolyRow, basis_rank
from fmu_fdi.design.problems.nullspace import undetectable_error
from fmu_fdi.design.toolkit.postconditions import DEC_TOL, check_generator
from fmu_fdi.generator import ResidualGenerator
from fmu_fdi.lti import LTI
from synthesis_models import aircraft_loop, contract, random_model, random_structure

# seeds 2, 3, 6, 13 returned contract-breaking designs before issue 13 (the whole set:
# benchmarks/synthesis_random_set.py, 17 of 80 calls on seeds 0-39); 0 and 37 kept it.
# A subset, for the test-time budget.
SEEDS = [0, 2, 3, 6, 13, 37]


@pytest.mark.parametrize("seed", SEEDS)
def test_random_model_design_keeps_contract_or_refuses(seed):
    model = random_model(seed)
    S = random_structure(model, seed)
    for call in (lambda: (nullspace_design(model), None), lambda: (structured_bank(model, S), S)):
        try:
            gen, S_req = call()
        except DesignError as exc:
            assert str(exc)  # a refusal names its reason
            continue
        assert contract(gen, model, S_req) == []
        assert "postconditions" in gen.info


def test_aircraft_loop_full_achievable_structure():
    """Lateral aircraft + actuators in series + dynamic controller in the loop (n = 8):
    every achievable specification (20 rows over 6 faults, Varga's fdigenspec set) in one
    least-order bank that passes every post-condition and isolates every fault."""
    from fmu_fdi.design.problems.achievable import achievable_structure

    model = aircraft_loop()
    S = achievable_structure(model)
    assert S.shape == (20, 6) and len({tuple(c) for c in S.T}) == 6  # distinct columns: all isolable
    # FDtol 1e-5: the actuator faults reach β and r only through Bu entries ~4e-4 against ~1.4
    bank = structured_bank(model, S, FDtol=1e-5)
    pc = bank.info["postconditions"]
    assert pc["decoupling"] < DEC_TOL and pc["structure_leak"] < DEC_TOL
    # rows are normalised to unit peak fault gain and ||Q|| ≤ ~3 here, so a relative leak below
    # DEC_TOL is an absolute block norm below 10·DEC_TOL
    assert structure_matrix(bank, tol=10 * DEC_TOL).tolist() == S.tolist()
    assert leakage(bank) < 10 * DEC_TOL
    assert contract(bank, model, S) == []
    # least order: each row of degree ν has ν states
    assert all(g.Q.n == g.info["order"] for g in bank.members)


def test_broken_filter_is_refused_with_numbers():
    gen = nullspace_design(pub.ex5_3(), rdim=1, poles=[-3])
    Q = gen.Q
    bad = ResidualGenerator(LTI(Q.A, Q.B, Q.C, Q.D + 1e-3), gen.model, "nullspace")
    with pytest.raises(DesignError, match=r"decoupling.*leak .* × the weakest fault gain > dec_tol"):
        check_generator(bad)


def test_stability_margin_option():
    with pytest.raises(DesignError, match="stability margin smarg = -5"):
        nullspace_design(pub.ex5_3(), rdim=1, poles=[-3], smarg=-5.0)
    gen = nullspace_design(pub.ex5_3(), rdim=1, poles=[-3], smarg=-2.0)
    assert gen.info["postconditions"]["pole_extreme"] == pytest.approx(-3.0)


def test_structured_bank_strong_at_freqs():
    bank = structured_bank(pub.ex5_3(), [[1, 1]], poles=[-3], freqs=[0.0])
    assert bank.info["postconditions"]["strong_gain_ratio"] > 0.01


def test_basis_rank_detects_shifted_rows():
    """The bug of issue 13: a row v and its shift μ·v form a 'basis' of rational rank 1."""
    v = np.array([[1.0, 2.0, -1.0], [0.5, 0.0, 1.0]])  # degree 1
    shifted = np.vstack([np.zeros((1, 3)), v])  # μ v(μ), degree 2
    rows = [PolyRow(1, v), PolyRow(2, shifted)]
    assert basis_rank(rows, 1.0, 0.0)[0] == 1
    assert basis_rank([PolyRow(1, v), PolyRow(0, np.array([[0.0, 1.0, 0.0]]))], 1.0, 0.0)[0] == 2


def test_detectable_fault_unseen_by_basis_does_not_claim_failed_rank():
    model = pub.ex5_3()
    err = undetectable_error(model, np.zeros((1, len(model.faults)), bool))
    msg = str(err)
    assert "satisfies the rank condition" in msg and "fails (" not in msg
