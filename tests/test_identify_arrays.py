"""FMI 3 array variables from a C model-exchange FMU (gcc): an array state is linearised per element
(``x[i]``), and so is an array output (``y[i]``)."""
from __future__ import annotations

import numpy as np
import pytest

from fmu_fdi.cli import main
from fmu_fdi.identify import IdentificationError, linearise

import me_fmus
from array_fmus import build_array_fmu
from cosim_fmus import fmi3_headers

pytestmark = pytest.mark.skipif(fmi3_headers() is None, reason="fmpy's FMI 3 headers are needed to build the FMU")


def test_array_state_is_linearised_per_element(tmp_path):
    lin = linearise(build_array_fmu(tmp_path), trim=True)
    assert lin.state_names == ["x[1]", "x[2]", "x[3]"] and lin.input_names == ["u1", "u2"]
    # central differences on a linear plant: exact up to rounding, eps/h ≈ 1e-16/6e-6 per unit of the
    # states' size (x ≈ 1): 1e-8 is a hundred times that
    for got, want in ((lin.A, me_fmus.A_LIN), (lin.B, me_fmus.B_LIN), (lin.C, me_fmus.C_LIN), (lin.D, me_fmus.D_LIN)):
        assert np.allclose(got, want, atol=1e-8), (got, want)
    # the trimmed state is the steady state -A⁻¹ B u0 (an independent solve)
    assert np.allclose(lin.x0, me_fmus.equilibrium("linear", np.array(me_fmus.PLANTS["linear"]["u_start"])),
                       atol=1e-9)


def test_array_output_is_linearised_per_element(tmp_path, capsys):
    """An array output is the vector of its elements y[1], y[2] (fmu_fdi/cosim/elements.py); naming the whole
    array is refused in one line that lists the element names to give instead."""
    fmu = build_array_fmu(tmp_path, array_output=True)
    with pytest.raises(IdentificationError, match=r"'y' is an FMI 3 array variable \(2 elements\).*y\[1\] y\[2\]"):
        linearise(fmu, outputs=["y"])
    lin = linearise(fmu, trim=True)
    assert lin.output_names == ["y[1]", "y[2]"]
    # the same tolerance as the array state's test above
    assert np.allclose(lin.C, me_fmus.C_LIN, atol=1e-8) and np.allclose(lin.D, me_fmus.D_LIN, atol=1e-8)
    assert main(["model", str(fmu), "-o", str(tmp_path / "m.toml")]) == 0
    assert "Traceback" not in capsys.readouterr().err
