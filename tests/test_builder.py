"""The diagnostic FMU's builder: the archive it writes is whole, loadable, truthful and
replaces a previous file only once it is complete (issues 11 and 12)."""
import json
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

MODEL = Path(__file__).parent.parent / "plant_fmus" / "dts200" / "dts200.toml"


@pytest.fixture(scope="module")
def dos(tmp_path_factory):
    """A dedicated observer scheme on the three tanks, saved and built once."""
    from fmu_fdi import Diagnoser, FDIModel, build_fmu, dedicated_bank

    tmp = tmp_path_factory.mktemp("builder")
    model = FDIModel.from_file(MODEL)
    dg = Diagnoser(dedicated_bank(model, "sensor", noise="ignore"), Ts=1.0, thresholds=0.4,
                   decision={"persistence": [3, 5]})
    return dg, dg.save(tmp / "dos.json"), build_fmu(dg, tmp / "dos.fmu")


def test_build_after_a_plant_fmu_ran_in_the_same_process_has_binaries(tmp_path, dos):
    """A pythonfmu plant FMU that ran first leaves its stripped pythonfmu copy (no wrapper
    binaries) in sys.modules; the build must still use the installed one, and the FMU must
    load. Run in a fresh process, as the demo does it: calibrate with the plant, then export.
    A diagnoser or plant that ran in the process can be built again (its stale module, bound
    to the FMU's pythonfmu copy, must not be what the builder inspects)."""
    import plant_fmus

    plant = plant_fmus.build("dts200", tmp_path)
    script = textwrap.dedent(f"""
        import json, sys, zipfile
        from fmu_fdi import CoSimulation, build_fmu
        CoSimulation({{"plant": {str(plant)!r}}}, None, step=1.0, stop=2.0).run()
        import pythonfmu
        shadowed = "resources" in pythonfmu.__file__     # the precondition of the bug
        fmu = build_fmu({str(dos[1])!r}, {str(tmp_path / "fdi.fmu")!r})
        res = CoSimulation({{"fdi": str(fmu)}}, None, step=1.0, stop=3.0, allow_unconnected=True).run()
        # the same bundle and the same plant, built again after they ran in this process
        again = build_fmu({str(dos[1])!r}, {str(tmp_path / "again.fmu")!r})
        import plant_fmus
        plant2 = plant_fmus.build("dts200", {str(tmp_path / "again")!r})
        print(json.dumps({{"shadowed": shadowed, "still": pythonfmu.__file__ == sys.modules["pythonfmu"].__file__,
                          "members": [zipfile.ZipFile(f).namelist() for f in (fmu, again, plant2)],
                          "rows": len(res)}}))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                          cwd=Path(__file__).parent.parent)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["shadowed"], "the plant FMU no longer shadows pythonfmu: this test reproduces nothing"
    assert out["still"]  # the process's own pythonfmu is left as it was
    import fmpy

    for members in out["members"]:
        assert any(m.startswith(f"binaries/{fmpy.platform}/") for m in members)
    assert out["rows"] == 4


def test_an_archive_without_binaries_is_refused(dos, tmp_path):
    from fmu_fdi.errors import BuildError
    from fmu_fdi.fmu.packaging import check_fmu_archive

    _, _, fmu = dos
    stripped = tmp_path / "stripped.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(stripped, "w") as dst:
        for info in src.infolist():
            if not info.filename.startswith("binaries/"):
                dst.writestr(info, src.read(info.filename))
    with pytest.raises(BuildError, match=r"no binaries/\w+/.* for this platform \(binaries for: none\)"):
        check_fmu_archive(stripped)
    with pytest.raises(BuildError, match="resources .*missing"):
        check_fmu_archive(fmu, ["nothere.py"])
    (tmp_path / "junk.fmu").write_bytes(b"not a zip")
    with pytest.raises(BuildError, match="not a readable FMU archive"):
        check_fmu_archive(tmp_path / "junk.fmu")


def test_a_failed_build_keeps_the_previous_fmu_and_leaves_no_debris(dos, tmp_path, monkeypatch):
    from fmu_fdi import build_fmu
    from fmu_fdi.errors import BuildError
    from fmu_fdi.fmu import packaging

    dg, _, _ = dos
    target = tmp_path / "fdi.fmu"
    target.write_bytes(b"the previous good FMU")

    def broken(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(packaging, "patch_fmu", broken)
    with pytest.raises(OSError, match="No space left"):
        build_fmu(dg, target)
    assert target.read_bytes() == b"the previous good FMU"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fdi.fmu"]
    folder = tmp_path / "folder.fmu"
    folder.mkdir()
    with pytest.raises(BuildError, match="is a folder; give a file name"):
        build_fmu(dg, folder)
    assert list(folder.iterdir()) == []
    with pytest.raises(BuildError, match="is a file, not a folder"):
        build_fmu(dg, target / "x.fmu")


def test_fmu_is_world_readable(dos):
    assert os.stat(dos[2]).st_mode & 0o777 == 0o644


def test_fmpy_info_shows_threshold_scale_stop_time_units_and_what_residuals_see(dos):
    import fmpy

    _, _, fmu = dos
    info = subprocess.run([sys.executable, "-m", "fmpy", "info", str(fmu)], capture_output=True, text=True,
                          timeout=120).stdout
    assert "threshold_scale" in info
    assert "Stop Time          1000.0" in info  # DEFAULT_SAMPLES = 1000 samples of Ts = 1 s
    platforms = sorted({m.split("/")[1] for m in zipfile.ZipFile(fmu).namelist() if m.startswith("binaries/")})
    assert f"Platforms          {', '.join(fmpy.supported_platforms(str(fmu)))}" in info
    assert sorted(fmpy.supported_platforms(str(fmu))) == platforms
    assert f"binaries: {', '.join(platforms)}" in info
    md = fmpy.read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    # the dedicated observer scheme: residual i sees sensor i and no other sensor
    for i in (1, 2, 3):
        desc = var[f"residual_{i}"].description
        assert f"sensor_h{i}" in desc and all(f"sensor_h{j}" not in desc for j in {1, 2, 3} - {i})
        assert var[f"residual_{i}"].unit == "cm" and var[f"evaluation_{i}"].unit == "cm"
        assert var[f"threshold_{i}"].unit == "cm"
    assert md.defaultExperiment.stepSize == "1.0"


def test_no_unit_is_claimed_when_the_outputs_differ():
    from fmu_fdi.designinfo import evaluation_unit, residual_unit

    design = {"units": {"y1": "cm", "y2": "rad"}, "signals": {"u": [], "y": ["y1", "y2"]},
              "generator": {"method": "nullspace"}, "evaluation": [{"evaluator": {"kind": "rms"}}]}
    assert residual_unit(design) is None and evaluation_unit(design, 0) is None
    design["units"]["y2"] = "cm"
    assert residual_unit(design) == "cm" and evaluation_unit(design, 0) == "cm"
    design["evaluation"][0]["evaluator"]["kind"] = "chi2"  # a χ² statistic is dimensionless
    assert evaluation_unit(design, 0) is None


def test_descriptions_of_a_design_without_isolation_use_its_computed_structure():
    """A null-space residual isolates nothing, so the design records no structure matrix:
    the descriptions then name the faults with a nonzero transfer to each group (the weak
    structure matrix of the generator), and claim nothing when that cannot be computed."""
    import published as pub

    from fmu_fdi import Diagnoser, nullspace_design, structure_matrix
    from fmu_fdi.designinfo import group_faults
    from fmu_fdi.designinfo import variable_descriptions as _descriptions

    gen = nullspace_design(pub.ex5_3(), poles=[-3])
    design = Diagnoser(gen, Ts=0.01, thresholds=1.0).design
    assert design["decision"].get("structure") is None
    expected = [[n for n, v in zip(gen.model.fault_names, row) if v] for row in structure_matrix(gen)]
    assert group_faults(design) == expected and expected[0]  # ex. 5.3: the residual sees fa and fs2
    assert f"sensitive to {', '.join(expected[0])}" in _descriptions(design)["residual_1"]
    del design["model"]  # nothing to compute it from
    assert group_faults(design) is None
    assert "not recorded" in _descriptions(design)["residual_1"]
