"""Design files of large plants: the embedded model's matrices in a binary sidecar beside the
design file (``design.json.npz``, docs/design-file.md), read back exactly, checked as a model
file's sidecar is, and carried into both FMU targets' resources (issue 20, item 2)."""
import hashlib
import json
import zipfile

import numpy as np
import pytest

import fmu_fdi.sidecar as sidecar
from fmu_fdi import Diagnoser, FDIModel, sensor_fault
from fmu_fdi.designfile import DesignFileError, load_design


def _diagnoser(n=8, seed=5):
    from fmu_fdi.design.problems.nullspace import nullspace_design

    rng = np.random.default_rng(seed)
    A = -2 * np.eye(n) + rng.standard_normal((n, n)) / np.sqrt(n)
    m = FDIModel.from_matrices(A, rng.standard_normal((n, 2)), rng.standard_normal((3, n)),
                               u_names=["u1", "u2"], y_names=["y1", "y2", "y3"],
                               faults=[sensor_fault(f"s{i}", f"y{i}") for i in (1, 2, 3)], name="side")
    return Diagnoser(nullspace_design(m), Ts=0.1, thresholds=1.0), m


@pytest.fixture
def small_threshold(monkeypatch):
    """Every model above 10 matrix entries goes to the sidecar (the default is 100 000: n ~ 300)."""
    monkeypatch.setattr(sidecar, "SIDECAR_MIN_ENTRIES", 10)


def _inputs(dg, N=40, seed=2):
    rng = np.random.default_rng(seed)
    return np.arange(N) * dg.Ts, rng.standard_normal((N, 2)), rng.standard_normal((N, 3))


def test_round_trip_through_the_sidecar_is_exact(tmp_path, small_threshold):
    dg, _ = _diagnoser()
    m = dg.generator.model  # the embedded model: the plant discretised at Ts
    path = dg.save(tmp_path / "d.json")
    side = tmp_path / "d.json.npz"
    assert side.is_file()
    text = json.loads(path.read_text())
    assert text["model"]["format"] == "fmu-fdi-model/2"
    assert text["model"]["matrices"]["A"] == {"array": "A", "shape": [8, 8]}  # no numbers left in the text
    assert text["model"]["arrays"]["sha256"] == hashlib.sha256(side.read_bytes()).hexdigest()
    with np.load(side, allow_pickle=False) as npz:  # plain float64 arrays: readable without pickle
        assert np.array_equal(npz["A"], m.A) and np.array_equal(npz["C"], m.C)
    back = Diagnoser.load(path)
    for key in ("A", "Bu", "C"):  # the embedded model, bit for bit
        assert np.array_equal(np.asarray(back.design["model"]["matrices"][key]), getattr(m, key)), key
    # the same diagnosis, bit for bit, judged against the diagnoser that was saved
    t, u, y = _inputs(dg)
    a, b = dg.run(t, u, y), back.run(t, u, y)
    assert all(np.array_equal(a[k], b[k]) for k in a.dtype.names)
    # the generator rebuilt from the embedded model has the saved one's internal form
    assert np.array_equal(back.generator.model.C, dg.generator.model.C)
    assert np.array_equal(back.generator.model.A, dg.generator.model.A)
    # saved again (now from arrays): the same files
    again = back.save(tmp_path / "e.json")
    assert (tmp_path / "e.json.npz").read_bytes() == side.read_bytes()
    assert json.loads(again.read_text())["model"]["arrays"]["file"] == "e.json.npz"


def test_a_small_design_stays_one_file_and_drops_a_stale_sidecar(tmp_path, monkeypatch):
    dg, _ = _diagnoser()
    m = dg.generator.model
    monkeypatch.setattr(sidecar, "SIDECAR_MIN_ENTRIES", 10)
    dg.save(tmp_path / "d.json")
    assert (tmp_path / "d.json.npz").is_file()
    monkeypatch.setattr(sidecar, "SIDECAR_MIN_ENTRIES", 100_000)
    path = dg.save(tmp_path / "d.json")
    assert not (tmp_path / "d.json.npz").exists()  # it would describe another save
    assert json.loads(path.read_text())["model"]["format"] == "fmu-fdi-model/1"
    assert np.array_equal(np.asarray(load_design(path)["model"]["matrices"]["A"]), m.A)


def _rewrite_digest(path):
    d = json.loads(path.read_text())
    d["model"]["arrays"]["sha256"] = hashlib.sha256((path.parent / d["model"]["arrays"]["file"]).read_bytes()).hexdigest()
    path.write_text(json.dumps(d))


def test_missing_changed_or_truncated_sidecar_is_refused(tmp_path, small_threshold):
    dg, _ = _diagnoser()
    path = dg.save(tmp_path / "d.json")
    side = tmp_path / "d.json.npz"
    good = side.read_bytes()
    side.write_bytes(good[:-1] + bytes([good[-1] ^ 1]))
    with pytest.raises(DesignFileError, match=r"d\.json: model: its sidecar .*d\.json\.npz is corrupt or was changed"):
        Diagnoser.load(path)
    side.write_bytes(good[: len(good) // 2])  # truncated, and the digest made to match
    _rewrite_digest(path)
    with pytest.raises(DesignFileError, match=r"is not a valid \.npz"):
        Diagnoser.load(path)
    side.unlink()
    with pytest.raises(DesignFileError, match=r"d\.json\.npz is missing"):
        load_design(path)
    # a design dict with references and no file to read them from
    d = json.loads(path.read_text())
    with pytest.raises(DesignFileError, match="only be read from a model file on disk"):
        Diagnoser.from_design(d)


def test_both_fmu_targets_carry_the_design_and_its_sidecar(tmp_path, small_threshold):
    from fmpy import simulate_fmu

    from fmu_fdi import build_fmu

    dg, _ = _diagnoser()
    m = dg.generator.model
    path = dg.save(tmp_path / "d.json")
    fmu = build_fmu(path, tmp_path / "d.fmu", target="native")
    with zipfile.ZipFile(fmu) as z:
        info = z.getinfo("resources/fmu_fdi/design.json.npz")
        assert info.compress_type == zipfile.ZIP_STORED  # float64 data does not deflate
        z.extract("resources/fmu_fdi/design.json", tmp_path / "x")
        z.extract("resources/fmu_fdi/design.json.npz", tmp_path / "x")
    copy = Diagnoser.load(tmp_path / "x" / "resources" / "fmu_fdi" / "design.json")  # a loadable design file
    assert np.array_equal(copy.design["model"]["matrices"]["A"], m.A)
    res = simulate_fmu(str(fmu), stop_time=1.0, output_interval=0.1)  # the C runtime starts and steps
    assert np.isfinite(res["residual_1"]).all()
    py = build_fmu(path, tmp_path / "p.fmu")
    with zipfile.ZipFile(py) as z:
        names = [n for n in z.namelist() if n.startswith("resources/") and "/design.json" in n]
    assert sorted(n.rsplit("/", 1)[1] for n in names) == ["design.json", "design.json.npz"]
    from fmu_fdi.cli import _design_file
    from fmu_fdi.errors import InputFileError

    with pytest.raises(InputFileError, match=r"diagnostic FMU.*unzip -j .*design\.json .*design\.json\.npz"):
        _design_file(fmu)  # given as a design file: the advice extracts the pair


def test_a_design_held_in_memory_with_arrays_is_still_checked(tmp_path, small_threshold):
    """A design read from a sidecar holds arrays; given back (edited) to from_design, its arrays are
    checked as a file's numbers are: a NaN or a string array is refused with the entry named."""
    dg, _ = _diagnoser()
    back = Diagnoser.load(dg.save(tmp_path / "d.json"))
    design = back.design
    assert isinstance(design["model"]["matrices"]["A"], np.ndarray)
    A = design["model"]["matrices"]["A"]
    design["model"]["matrices"]["A"] = A.copy()
    design["model"]["matrices"]["A"][1, 2] = np.nan
    with pytest.raises(DesignFileError, match=r"matrix A has a non-finite or too large entry \[2\]\[3\] = nan"):
        Diagnoser.from_design(design)
    design["model"]["matrices"]["A"] = A.astype(str)
    with pytest.raises(DesignFileError, match="matrix A must be an array of real numbers"):
        Diagnoser.from_design(design)
    design["model"]["matrices"]["A"] = A
    assert np.array_equal(Diagnoser.from_design(design).generator.model.A, A)  # the original is accepted
