"""ResidualGenerator's blocks Ru, Rd, Rw, Rf are each one column slice of the one minimal realisation of
R = Q·[Gu Gd Gw Gf; I 0 0 0] (reduced once and kept, not all four blocks per property read), and a
row scaling (``scale_rows``) reaches them: judged by numpy on the frequency responses of Q and the
plant's blocks (an independent computation, not the library's analysis).
"""
import numpy as np
import pytest

from fmu_fdi import FDIModel, actuator_fault, sensor_fault
from fmu_fdi.design import nullspace_design


def _fr(A, B, C, D, lam):
    n = A.shape[0]
    return np.array([C @ np.linalg.solve(l * np.eye(n) - A, B) + D if n else D + 0j for l in lam])


def _model():
    rng = np.random.default_rng(7)
    n, p, m = 4, 3, 2
    A = np.diag([-1.0, -2.0, -0.5, -3.0]) + 0.1 * rng.standard_normal((n, n))
    B, C = rng.standard_normal((n, m)), rng.standard_normal((p, n))
    Bd, Bw = rng.standard_normal((n, 1)), rng.standard_normal((n, 1))
    return FDIModel.from_matrices(A, B, C, np.zeros((p, m)), Bd=Bd, Dd=np.zeros((p, 1)), Bw=Bw,
                                  Dw=np.zeros((p, 1)), faults=[sensor_fault("fs1", "y1"), actuator_fault("fa1", "u1")],
                                  u_names=["u1", "u2"], y_names=["y1", "y2", "y3"])


def _numpy_blocks(gen, lam):
    """Q(λ)·[Gu Gd Gw Gf; I 0 0 0] by numpy, split into its u, d, w, f columns."""
    m = gen.model
    Ge = _fr(m.A, np.hstack([m.Bu, m.Bd, m.Bw, m.Bf]), m.C, np.hstack([m.Du, m.Dd, m.Dw, m.Df]), lam)
    eye = np.zeros((m.nu, Ge.shape[2]))
    eye[:, :m.nu] = np.eye(m.nu)
    Q = gen.Q
    R = _fr(Q.A, Q.B, Q.C, Q.D, lam) @ np.concatenate([Ge, np.broadcast_to(eye, (len(lam),) + eye.shape)], axis=1)
    k = np.cumsum([0, m.nu, m.nd, m.nw, m.nf])
    return {g: R[:, :, k[i]:k[i + 1]] for i, g in enumerate("udwf")}


@pytest.mark.parametrize("scale", [1.0, 1e3])
def test_blocks_are_numpys_and_follow_row_scaling(scale):
    gen = nullspace_design(_model())
    lam = 1j * np.logspace(-2, 2, 9)
    _ = gen.Rf, gen.Ru  # reduced and kept before the scaling: scale_rows must forget them
    gen.scale_rows(np.full(gen.Q.p, scale))
    ref = _numpy_blocks(gen, lam)
    # |R_f(λ)| is O(scale) on these points; a block read on its minimal realisation agrees to a few
    # hundred eps of the data's norm (|Q|·|Ge| ≲ 1e2·scale); 1e-9 relative leaves a margin of 1e4
    big = max(np.abs(ref["f"]).max(), 1e-300)
    for g, X in (("u", gen.Ru), ("d", gen.Rd), ("w", gen.Rw), ("f", gen.Rf)):
        assert np.allclose(X.freqresp(lam.imag), ref[g], rtol=0, atol=1e-9 * big), g
        assert X is gen.internal_form()[g]  # one reduction per block, shared by internal_form
    # exact decoupling of u and d (the design's post-condition), read by numpy
    assert np.abs(ref["u"]).max() <= 1e-7 * big and np.abs(ref["d"]).max() <= 1e-7 * big


def test_structurally_observed_keeps_every_state_with_a_path_to_the_output():
    from fmu_fdi.generator import structurally_observed

    # x0 is read by C; x2 drives x0 (A[0, 2]); x1 is driven by x0 (A[1, 0]) but drives nothing read; x3 alone
    A = np.array([[-1.0, 0.0, 2.0, 0.0], [3.0, -2.0, 0.0, 0.0], [0.0, 0.0, -3.0, 0.0], [0.0, 0.0, 0.0, -4.0]])
    B, C, D = np.ones((4, 1)), np.array([[1.0, 0.0, 0.0, 0.0]]), np.zeros((1, 1))
    keep = structurally_observed(A, C)
    assert keep.tolist() == [0, 2]
    lam = 1j * np.logspace(-2, 2, 7)
    full = _fr(A, B, C, D, lam)
    part = _fr(A[np.ix_(keep, keep)], B[keep], C[:, keep], D, lam)
    # the dropped states are unobservable exactly: the two responses agree to rounding (|G| ≤ 1.5 here)
    assert np.allclose(part, full, rtol=0, atol=1e-14)
    assert structurally_observed(A, np.zeros((1, 4))).size == 0


def test_a_banks_group_is_read_on_its_own_members_states():
    from fmu_fdi.design import structured_bank

    model = _model()
    bank = structured_bank(model, np.array([[1, 0], [0, 1]]))
    lam = 1j * np.logspace(-2, 2, 9)
    full = _numpy_blocks(bank, lam)
    for i, (g, member) in enumerate(zip(bank.groups, bank.members)):
        Ri = bank.group_internal_form(i)
        assert Ri.n <= member.Q.n + model.n  # not the stacked bank's Σ n(Q_j) + n
        ref = np.concatenate([full[k][:, g, :] for k in "udwf"], axis=2)
        big = np.abs(ref).max()
        # the same transfer function as the rows g of Q·Ge (numpy on the whole stacked Q); 1e-9 as above
        assert np.allclose(Ri.freqresp(lam.imag), ref, rtol=0, atol=1e-9 * big), i
