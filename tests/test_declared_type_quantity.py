"""A declared type's attributes (``quantity``, ``unit``, ``displayUnit``) travel from the plant FMU's
TypeDefinitions through the model file (``[type_definitions]``; files without it still load) into the
diagnostic FMU's TypeDefinitions (``quantity`` and the shared unit), read back with independent parsers
(tomllib, ElementTree, fmpy)."""
from __future__ import annotations

import tomllib
import zipfile
from xml.etree import ElementTree as ET

import pytest

from fmu_fdi import FDIModel
from fmu_fdi.cli import main
from fmu_fdi.faults import ModelError

import array_io_fmus as P
from cosim_fmus import fmi3_headers


def _model(**kw):
    return FDIModel(P.A, P.B[:, :1], P.C, P.D[:, :1], u_names=["u[1]"], y_names=["y[1]", "y[2]"],
                    units={"u[1]": "N", "y[1]": "m", "y[2]": "m"},
                    declared_types={"u[1]": "Force", "y[1]": "Position", "y[2]": "Position"}, **kw)


DEFS = {"Force": {"quantity": "Force", "unit": "N", "displayUnit": "kN"}, "Position": {"quantity": "Length"}}


def test_model_file_keeps_type_attributes_and_old_files_load(tmp_path):
    m = _model(type_definitions={**DEFS, "Unused": {"quantity": "Time"}})
    for ext in ("toml", "json"):
        m.to_file(tmp_path / f"m.{ext}")
        assert FDIModel.from_file(tmp_path / f"m.{ext}").type_definitions == DEFS  # an unused type is not written
    with open(tmp_path / "m.toml", "rb") as fh:
        d = tomllib.load(fh)
    assert d["type_definitions"]["Force"] == {"quantity": "Force", "unit": "N", "displayUnit": "kN"}
    # a file of the old format (no [type_definitions]) loads, with no attributes
    text = (tmp_path / "m.toml").read_text()
    old = text[:text.index("[type_definitions]")] + text[text.index("\n[", text.index("[type_definitions]") + 1) + 1:]
    (tmp_path / "old.toml").write_text(old)
    m_old = FDIModel.from_file(tmp_path / "old.toml")
    assert m_old.type_definitions == {} and m_old.declared_types == m.declared_types
    with pytest.raises(ModelError, match="type definition 'Force': unknown attributes \\['nominal'\\]"):
        _model(type_definitions={"Force": {"nominal": "1"}})
    with pytest.raises(ModelError, match="quantity must be a string"):
        _model(type_definitions={"Force": {"quantity": 3}})


@pytest.mark.skipif(fmi3_headers() is None, reason="fmpy's FMI 3 headers are needed to build the FMU")
def test_quantity_reaches_the_model_file_and_the_diagnostic_fmu(tmp_path):
    """The array test FMU declares ``Force`` (quantity Force, unit N) and ``Position`` (quantity Length,
    unit m): ``fmu-fdi model`` keeps both, and every diagnostic FMU target writes the quantity on the type."""
    from fmpy import read_model_description

    from fmu_fdi.fmu.builder import build_fmu

    plant = P.build_array_io_fmu(tmp_path)
    assert main(["model", str(plant), "--sensor-faults", "all", "-o", str(tmp_path / "m.toml")]) == 0
    with open(tmp_path / "m.toml", "rb") as fh:
        d = tomllib.load(fh)
    assert d["type_definitions"] == {"Force": {"quantity": "Force", "unit": "N"},
                                     "Position": {"quantity": "Length", "unit": "m"}}
    assert main(["design", str(tmp_path / "m.toml"), "--method", "dos", "--ts", "0.05", "-o",
                 str(tmp_path / "d.json")]) == 0
    for target, fmi in (("pythonfmu", 2), ("native", 3)):
        fmu = build_fmu(tmp_path / "d.json", tmp_path / f"{target}{fmi}.fmu", target=target, fmi_version=fmi)
        with zipfile.ZipFile(fmu) as zf:
            root = ET.fromstring(zf.read("modelDescription.xml"))
        if fmi == 2:
            defs = {t.get("name"): dict(t.find("Real").attrib) for t in root.findall("TypeDefinitions/SimpleType")}
        else:
            defs = {t.get("name"): {k: v for k, v in t.attrib.items() if k != "name"}
                    for t in root.findall("TypeDefinitions/Float64Type")}
        assert defs == {"Force": {"quantity": "Force", "unit": "N"},
                        "Position": {"quantity": "Length", "unit": "m"}}, (target, fmi)
        md = read_model_description(str(fmu), validate=True)
        assert {t.name: t.quantity for t in md.typeDefinitions} == {"Force": "Force", "Position": "Length"}
