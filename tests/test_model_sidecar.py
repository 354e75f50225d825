"""Model files with a binary array sidecar (fmu-fdi-model/2, docs/model-file.md) and the
structured frequency-response path of large models (docs/large-models.md)."""
import hashlib
import io
import json
import re
import zipfile

import numpy as np
import pytest

from fmu_fdi import FDIModel, ModelError, actuator_fault, component_fault, parametric_fault, sensor_fault
from fmu_fdi.sidecar import SIDECAR_MIN_ENTRIES


def _model(n=6, seed=3):
    rng = np.random.default_rng(seed)
    A = -2 * np.eye(n) + rng.standard_normal((n, n)) / np.sqrt(n)
    return FDIModel.from_matrices(
        A, rng.standard_normal((n, 2)), rng.standard_normal((3, n)), Bd=rng.standard_normal((n, 1)),
        u_names=["u1", "u2"], y_names=["y1", "y2", "y3"], d_names=["d1"],
        faults=[sensor_fault("s1", "y1"), actuator_fault("a1", "u1"),
                component_fault("leak", rng.standard_normal((n, 1))), parametric_fault("drift", dA=0.1 * np.eye(n))],
        name="side")


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_sidecar_round_trip_is_exact(tmp_path, suffix):
    m = _model()
    path = m.to_file(tmp_path / f"m{suffix}", sidecar=True)
    side = tmp_path / f"m{suffix}.npz"
    text = path.read_text()
    assert side.is_file() and "fmu-fdi-model/2" in text
    assert not re.search(r"\d\.\d{6}", text)  # no matrix entries left in the text
    with np.load(side, allow_pickle=False) as npz:  # plain float64 arrays, readable without pickle
        assert np.array_equal(npz["A"], m.A) and all(npz[k].dtype == np.float64 for k in npz.files)
    m2 = FDIModel.from_file(path)
    for key in ("A", "Bu", "C", "Du", "Bd", "Dd", "Bf", "Df"):
        assert np.array_equal(getattr(m2, key), getattr(m, key)), key
    assert m2.fault_names == m.fault_names and np.array_equal(m2.fault("drift").dA, m.fault("drift").dA)


def test_the_sidecar_is_chosen_by_size(tmp_path):
    small = _model()
    assert json.loads(small.to_file(tmp_path / "s.json").read_text())["format"] == "fmu-fdi-model/1"
    assert not (tmp_path / "s.json.npz").exists()
    n = int(np.sqrt(SIDECAR_MIN_ENTRIES)) + 1  # A alone holds more than the threshold
    big = FDIModel.from_matrices(-np.eye(n), np.ones((n, 1)), np.ones((1, n)))
    path = big.to_file(tmp_path / "b.toml")
    assert (tmp_path / "b.toml.npz").is_file() and path.stat().st_size < 2000
    assert np.array_equal(FDIModel.from_file(path).A, -np.eye(n))
    path = big.to_file(tmp_path / "t.json", sidecar=False)  # asked for text: one file
    assert not (tmp_path / "t.json.npz").exists() and np.array_equal(FDIModel.from_file(path).A, -np.eye(n))
    path = big.to_file(tmp_path / "b.toml", sidecar=False)  # the same name as text: the earlier sidecar goes
    assert not (tmp_path / "b.toml.npz").exists() and np.array_equal(FDIModel.from_file(path).A, -np.eye(n))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.toml", "s.json", "t.json"]  # no temporary left


def _rewrite_digest(path):
    """Record the sidecar's present SHA-256 in the model file (JSON), so a check past the digest runs."""
    d = json.loads(path.read_text())
    d["arrays"]["sha256"] = hashlib.sha256((path.parent / d["arrays"]["file"]).read_bytes()).hexdigest()
    path.write_text(json.dumps(d))


def test_missing_or_corrupt_sidecar_is_refused(tmp_path):
    path = _model().to_file(tmp_path / "m.json", sidecar=True)
    side = tmp_path / "m.json.npz"
    good = side.read_bytes()
    side.write_bytes(good[:-1] + bytes([good[-1] ^ 1]))
    with pytest.raises(ModelError, match=r"corrupt or was changed: SHA-256"):
        FDIModel.from_file(path)
    side.unlink()
    with pytest.raises(ModelError, match=r"m\.json: its sidecar .*m\.json\.npz is missing"):
        FDIModel.from_file(path)
    side.write_bytes(b"not a zip at all")
    _rewrite_digest(path)
    with pytest.raises(ModelError, match="not a valid .npz"):
        FDIModel.from_file(path)


def _rezip(side, model_path, edit):
    """Rewrite the sidecar with ``edit`` applied to the bytes of its member A.npy (the zip itself
    stays valid, CRCs included) and record its digest, so the check of the member runs."""
    with zipfile.ZipFile(side) as z:
        members = {k: z.read(k) for k in z.namelist()}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for k, v in members.items():
            z.writestr(k, edit(v) if k == "A.npy" else v)
    side.write_bytes(buf.getvalue())
    _rewrite_digest(model_path)


@pytest.mark.parametrize("how, edit", [
    ("truncated data", lambda b: b[:-8]),                              # fewer bytes than the header announces
    ("damaged header", lambda b: b[:10] + b"garbage" + b[17:]),        # the header dict no longer parses
    ("not an .npy", lambda b: b"XX" + b[2:]),                          # the magic string is gone
    ("unknown version", lambda b: b[:6] + bytes([9, 0]) + b[8:]),
])
def test_damaged_sidecar_members_are_one_line_errors(tmp_path, how, edit):
    path = _model().to_file(tmp_path / "m.json", sidecar=True)
    _rezip(tmp_path / "m.json.npz", path, edit)
    with pytest.raises(ModelError, match=r"m\.json: matrix A: array 'A' of the sidecar .*m\.json\.npz is damaged: "):
        FDIModel.from_file(path)


def test_truncated_or_bit_flipped_sidecar_with_a_matching_digest_is_refused(tmp_path):
    """Past the digest (a sidecar replaced together with its model file's digest): a cut zip is not
    an .npz, a flipped data bit fails the member's CRC."""
    path = _model().to_file(tmp_path / "m.json", sidecar=True)
    side = tmp_path / "m.json.npz"
    good = side.read_bytes()
    for cut in (0, 100, len(good) // 2, len(good) - 1):
        side.write_bytes(good[:cut])
        _rewrite_digest(path)
        with pytest.raises(ModelError, match="is not a valid .npz"):
            FDIModel.from_file(path)
    flipped = bytearray(good)
    flipped[good.index(b"\x93NUMPY") + 200] ^= 0xFF  # inside A's data (A.npy is the first member)
    side.write_bytes(bytes(flipped))
    _rewrite_digest(path)
    with pytest.raises(ModelError, match=r"array 'A' of the sidecar .* is damaged: Bad CRC-32"):
        FDIModel.from_file(path)


def _write_npz(path, model_path, **arrays):
    np.savez(path, **arrays)  # allow_pickle defaults to True here: object arrays get pickled
    _rewrite_digest(model_path)


def test_pickled_non_finite_or_misshapen_arrays_are_refused(tmp_path):
    m = _model()
    path = m.to_file(tmp_path / "m.json", sidecar=True)
    side = tmp_path / "m.json.npz"
    with np.load(side, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    pickled = dict(arrays, A=np.array([[object()]], dtype=object))
    _write_npz(side, path, **pickled)
    with pytest.raises(ModelError, match="cannot be read without pickle"):
        FDIModel.from_file(path)
    bad = dict(arrays, A=arrays["A"].copy())
    bad["A"][2, 3] = np.nan
    _write_npz(side, path, **bad)
    with pytest.raises(ModelError, match=r"matrix A: .*non-finite or too large entry \[3\]\[4\]"):
        FDIModel.from_file(path)
    _write_npz(side, path, **dict(arrays, A=arrays["A"][:, :-1]))
    with pytest.raises(ModelError, match=r"shape \(6, 5\), the model file records \(6, 6\)"):
        FDIModel.from_file(path)
    _write_npz(side, path, **dict(arrays, A=arrays["A"].astype(np.float32)))
    with pytest.raises(ModelError, match="float32, expected float64"):
        FDIModel.from_file(path)
    _write_npz(side, path, **{k: v for k, v in arrays.items() if k != "C"})
    with pytest.raises(ModelError, match="array 'C' is not in the sidecar"):
        FDIModel.from_file(path)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["arrays"].update(file="../m.json.npz"), "must be a file name in the model file's folder"),
    (lambda d: d.update(format="fmu-fdi-model/1"), "needs format = 'fmu-fdi-model/2'"),
    (lambda d: d.pop("arrays"), "refers to a sidecar array but the file has no"),
    (lambda d: d["matrices"]["A"].update(shape=[6]), r"shape must be \[rows, columns\]"),
])
def test_malformed_sidecar_references(tmp_path, edit, message):
    path = _model().to_file(tmp_path / "m.json", sidecar=True)
    d = json.loads(path.read_text())
    edit(d)
    path.write_text(json.dumps(d))
    with pytest.raises(ModelError, match=message):
        FDIModel.from_file(path)


def test_an_embedded_model_cannot_use_a_sidecar(tmp_path):
    path = _model().to_file(tmp_path / "m.json", sidecar=True)
    with pytest.raises(ModelError, match="only be read from a model file on disk"):
        FDIModel.from_dict(json.loads(path.read_text()))


# ------------------------------------------------ the fast analysis path against the old one
def _old_normal_rank(G, points=3, seed=0):
    """The pre-sidecar normal rank, independent of the code under test: eigvals for the
    scale and a dense LU solve (numpy.linalg.solve) per random point, per sub-system."""
    if G.m == 0 or G.p == 0:
        return 0
    rng = np.random.default_rng(seed)
    scale = max(1.0, float(np.max(np.abs(np.linalg.eigvals(G.A)), initial=0.0))) if G.n else 1.0
    best = 0
    for _ in range(points):
        lam = scale * (rng.uniform(0.5, 2.0) + 1j * rng.uniform(0.5, 2.0))
        if G.is_discrete:
            lam = np.exp(1j * rng.uniform(0.3, 2.8)) * rng.uniform(1.1, 1.5)
        H = G.C @ np.linalg.solve(lam * np.eye(G.n) - G.A, G.B) + G.D if G.n else G.D
        s = np.linalg.svd(H, compute_uv=False)
        best = max(best, int(np.sum(s > max(H.shape) * np.finfo(float).eps * 1e3 * s[0])) if s.size else 0)
    return best


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("dt", [0.0, 0.1])
def test_isolability_and_detectability_equal_the_old_path(seed, dt):
    from fmu_fdi.analysis import detectability, isolability

    rng = np.random.default_rng(seed)
    n = 7
    A = -np.eye(n) + 0.3 * rng.standard_normal((n, n)) if not dt else 0.3 * rng.standard_normal((n, n))
    Bd = rng.standard_normal((n, 1))
    # faults 'c0' and 'c1' share a direction with d (rank-deficient pairs), the rest are generic
    m = FDIModel.from_matrices(A, rng.standard_normal((n, 2)), rng.standard_normal((3, n)), Bd=Bd, dt=dt,
                               faults=[sensor_fault("s0", "y0"), actuator_fault("a0", "u0"),
                                       component_fault("c0", 2 * Bd), component_fault("c1", Bd + 1e-3 * 0),
                                       component_fault("c2", rng.standard_normal((n, 1)))])
    G = m.lti("d", "f")
    cols = {f.name: [m.nd + j for j in range(m.nf)[f.columns]] for f in m.faults}
    iso = isolability(m)
    for i, fi in enumerate(m.fault_names):
        for j, fj in enumerate(m.fault_names):
            if i != j:
                base = [0] + cols[fj]
                assert iso["matrix"][i, j] == (_old_normal_rank(G[:, base + cols[fi]]) > _old_normal_rank(G[:, base]))
    full = _old_normal_rank(G) == _old_normal_rank(m.lti("d")) + sum(_old_normal_rank(G[:, c]) for c in cols.values())
    assert iso["fully_isolable"] == full
    det = detectability(m)
    for name, c in cols.items():
        assert det[name]["detectable"] == (_old_normal_rank(G[:, [0] + c]) > _old_normal_rank(m.lti("d")))


@pytest.mark.parametrize("dt", [0.0, 0.05])
def test_structured_frequency_response_equals_dense_solves(dt):
    """LTI.freqresp (one Hessenberg form, O(n²) per point) against a dense LU solve per point.
    Both are backward stable, so they agree to a few eps times cond(λI - A) (here < 1e3)."""
    from fmu_fdi.lti import LTI

    rng = np.random.default_rng(7)
    for n in (1, 2, 9, 40):
        A = -1.5 * np.eye(n) + rng.standard_normal((n, n)) / np.sqrt(n)
        if dt:
            A = 0.5 * A / np.max(np.abs(np.linalg.eigvals(A)))
        G = LTI(A, rng.standard_normal((n, 3)), rng.standard_normal((2, n)), rng.standard_normal((2, 3)), dt)
        omega = np.linspace(0.0, 30.0, 25)
        H = G.freqresp(omega)
        for k, w in enumerate(omega):
            lam = np.exp(1j * w * dt) if dt else 1j * w
            M = lam * np.eye(n) - A
            ref = G.C @ np.linalg.solve(M, G.B) + G.D
            tol = 100 * n * np.finfo(float).eps * np.linalg.cond(M) * max(1.0, np.abs(ref).max())
            assert np.abs(H[k] - ref).max() <= tol, (n, w)


def test_staircase_rotations_equal_the_dense_products():
    """pencil._rotate (trailing block only) equals Zᵀ a Z, Zᵀ b, c Z with the dense Z."""
    from fmu_fdi.design.toolkit.pencil import _rotate

    rng = np.random.default_rng(2)
    n = 8
    a, b, c = rng.standard_normal((n, n)), rng.standard_normal((n, 3)), rng.standard_normal((2, n))
    U, _ = np.linalg.qr(rng.standard_normal((5, 5)))
    Z = np.eye(n)
    Z[3:, 3:] = U
    ref = Z.T @ a @ Z, Z.T @ b, c @ Z
    _rotate(U, slice(3, n), a, rows=(b,), cols=(c,))
    for got, want in zip((a, b, c), ref):
        assert np.allclose(got, want, rtol=0, atol=10 * n * np.finfo(float).eps * np.abs(want).max())
