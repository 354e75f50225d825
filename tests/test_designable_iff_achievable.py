"""Designable iff achievable (issue 17, Build item 3): for every candidate structure row,
``structured_bank(model, [row])`` succeeds iff ``achievable_structure`` (same ``freqs``,
``FDGainTol``, ``atol``) lists it — on the published examples and on seeded random models.

Before (integ at 9fe9cb4, strong rows decided by a projection test on the minimal polynomial
basis): random seed 9 listed [1 1 0 1 0] and the bank refused it (fault gain 0.0039 at ω = 0 <
FDGainTol = 0.01 on the designed row); seeds 10 and 16 listed 3 and 4 rows whose every design keeps
~1e-7 at ω = 0; seeds 3, 8, 10, 17 did not list rows the core designs (refused only by the
pre-check). The published sets (Boeing 747, Yuan, Niemann, Xiong–Saif) agreed.

A designed row is judged independently (numpy frequency responses, tests/test_synthesis_random.py's
``judge``), and with ``freqs`` its normalised gains at every ω are recomputed here. A row the weak
rank test refuses is also refused by the core itself when the pre-check is bypassed.
"""
import itertools

import numpy as np
import pytest
from test_synthesis_published import boeing747, niemann, xiong_saif_1, xiong_saif_2, yuan
from test_synthesis_random import _extended, _freqresp, _grid, judge, random_case

import fmu_fdi.analysis as analysis
from fmu_fdi import DesignError, structured_bank
from fmu_fdi.design.problems.achievable import achievable_structure

STRONG = {"freqs": [0.0, 1.0], "FDGainTol": 1e-2}
#: at most this many rows the rank test refuses are sent through the core without the pre-check
#: (seeded sample): each is a full design attempt
CORE_SAMPLE = 6


def _strong_gains(bank, model, names, row, freqs) -> np.ndarray:
    """Gains ``||R_fj(jω)||`` of the required faults on the row normalised to unit weakest fault peak,
    from the plant's and the filter's frequency responses (no fmu_fdi analysis code). At ω the value is
    taken at ω + 1e-7·max(1, ω) (the limit at a pole of the plant on the axis; a smooth response moves by
    O(1e-7), far below FDGainTol)."""
    A, B, C, D = _extended(model)
    Q = bank.Q
    f0 = model.nu + model.nd + model.nw
    cols = {f.name: f0 + np.arange(model.nf)[f.columns] for f in model.faults}
    req = [nm for nm, s in zip(names, row) if s]
    lam = _grid(model, np.linalg.eigvals(Q.A) if Q.A.shape[0] else ())
    R = _freqresp(Q.A, Q.B, Q.C, Q.D, lam) @ _freqresp(A, B, C, D, lam)
    weakest = min(np.linalg.norm(R[:, :, cols[nm]], 2, axis=(1, 2)).max() for nm in req)
    w = np.asarray(freqs, float)
    w = w + 1e-7 * np.maximum(1.0, w)
    pts = np.exp(1j * w * model.dt) if model.dt else 1j * w
    Rs = _freqresp(Q.A, Q.B, Q.C, Q.D, pts) @ _freqresp(A, B, C, D, pts)
    return np.array([[np.linalg.norm(Rs[k][:, cols[nm]], 2) for k in range(w.size)] for nm in req]) / weakest


def _core_refuses(model, names, row, kw) -> bool:
    """structured_bank of the row with its weak pre-check bypassed: the core alone decides."""
    orig = analysis.row_test
    analysis.row_test = lambda *a, **k: (lambda r: None)
    try:
        structured_bank(model, [list(row)], faults=names, **kw)
    except DesignError:
        return True
    finally:
        analysis.row_test = orig
    return False


def _check(model, kw, seed=0):
    names = model.fault_names
    listed = {tuple(r) for r in achievable_structure(model, **kw).tolist()}
    weak = listed if not kw else {tuple(r) for r in achievable_structure(model).tolist()}
    problems, unlisted = [], []
    for row in itertools.product((0, 1), repeat=len(names)):
        if not any(row):
            continue
        try:
            bank = structured_bank(model, [list(row)], faults=names, **kw)
        except DesignError as exc:
            if row in listed:
                problems.append(f"{row} listed but refused: {str(exc)[:160]}")
            elif row not in weak:
                unlisted.append(row)
            continue
        if row not in listed:
            problems.append(f"{row} designed but not listed")
            continue
        problems += [f"{row}: {v}" for v in judge(bank, model, [row], names)]
        if kw.get("freqs") is not None:
            g = _strong_gains(bank, model, names, row, kw["freqs"])
            # the judge's peak is on its own grid (log-spaced, ≥ 160 points, the same pole scales): two
            # grid estimates of a peak agree within a few %, so 10 % slack on FDGainTol
            if not np.all(g >= 0.9 * kw["FDGainTol"]):
                problems.append(f"{row}: normalised gains at {kw['freqs']} are {g.min():.3g} < FDGainTol")
    rng = np.random.default_rng(seed)
    for k in rng.permutation(len(unlisted))[:CORE_SAMPLE]:
        if not _core_refuses(model, names, unlisted[k], {}):
            problems.append(f"{unlisted[k]} refused by the rank test but designed by the core")
    return listed, problems


@pytest.mark.parametrize("make", [niemann, xiong_saif_1, xiong_saif_2])
@pytest.mark.parametrize("kw", [{}, {"freqs": [0.0, 1.0], "FDGainTol": 1e-3}], ids=["weak", "strong"])
def test_textbook_examples(make, kw):
    listed, problems = _check(make(), kw)
    assert len(listed) == 3 and problems == []


def test_boeing747_weak():
    listed, problems = _check(boeing747(), {})
    assert len(listed) == 7 and problems == []


@pytest.mark.slow  # 7 weak rows designed twice (listing, then the bank): ~20 s on a loaded machine
def test_boeing747_strong():
    """FDGainTol = 1e-2 at ω = [0, 1]: the peer's 4 rows (fdigenspec), each designed."""
    listed, problems = _check(boeing747(), STRONG)
    assert len(listed) == 4 and problems == []


@pytest.mark.slow  # 18 weak rows designed twice
def test_yuan_strong():
    listed, problems = _check(yuan(), {"freqs": [0.0, 1.0], "FDGainTol": 1e-3})
    assert len(listed) == 12 and problems == []


@pytest.mark.parametrize("seed", [3, 9, 10, 16])
@pytest.mark.parametrize("kw", [{}, STRONG], ids=["weak", "strong"])
def test_random_models(seed, kw):
    """Seeds where integ's two tests disagreed (module docstring), weak and strong at ω = [0, 1]."""
    _, problems = _check(random_case(seed), kw, seed)
    assert problems == []
