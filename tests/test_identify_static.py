"""Static plants (order 0) and pure feedthroughs from third-party-like C FMUs (FMI 3 co-simulation,
built with gcc): ``fmu-fdi model`` with default options and with ``--order 0``, their noise on,
a discrete Int32 input held at its start value."""
from __future__ import annotations

import numpy as np
import pytest

from fmu_fdi import FDIModel
from fmu_fdi.cli import main

from cosim_fmus import fmi3_headers
from static_fmus import build_static_fmu

pytestmark = pytest.mark.skipif(fmi3_headers() is None, reason="fmpy's FMI 3 headers are needed to build the FMU")

K = [[2.0, -1.0], [0.5, 1.0]]


@pytest.mark.parametrize("order", [None, pytest.param(0, marks=pytest.mark.slow)])
def test_static_plant_is_a_gain_with_no_state(tmp_path, capsys, order):
    fmu = build_static_fmu(tmp_path, K, offset=[0.3, 0.0])
    out = tmp_path / "m.toml"
    args = ["model", str(fmu), "--inputs", "u1", "u2", "--outputs", "y1", "y2", "-o", str(out)]
    # with --order 0 the discrete input is given (--at mode=2): held there, set before initialisation
    mode = 1 if order is None else 2
    assert main(args + ([] if order is None else ["--order", str(order), "--at", "mode=2"])) == 0
    text = capsys.readouterr()
    assert "Traceback" not in text.out + text.err and "validation fit (order 0)" in text.out
    m = FDIModel.from_file(out)
    assert m.n == 0 and m.provenance["order"] == 0 and m.provenance["method"].startswith("static gain")
    # least squares on N ≈ 1000 samples: the gain's std is σ/(a √N) per entry (σ = 0.01 noise, a the input
    # amplitude, ≥ 0.05); 6 standard deviations: 6 · 0.01 / (0.05 · 31) ≈ 0.04
    a = min(float(s.split("=")[1]) for s in m.provenance["excitation"].split("amplitudes ")[1].split(", "))
    N = m.provenance["samples"]
    assert np.abs(m.Du - np.array(K)).max() < 6 * 0.01 / (a * np.sqrt(N)), (m.Du, a, N)
    # operating point: y0 = K u0 + offset + mode (the discrete input held at its start 1, or at 2, on y1)
    # (y0 is the settled mean over the last 50 samples of settling: σ/√50 = 0.0014; 0.01 is 7 of them)
    assert np.allclose(m.y0, np.array(K) @ m.u0 + [0.3 + mode, 0.0], atol=0.01), (m.u0, m.y0)
    # the noise model: the sensor noise, σ = 0.01 on each output (its sample std over N: ± 5 % at 6 std)
    assert m.provenance["noise_model"] == "innovation"
    assert np.allclose(np.sqrt(np.diag(m.Dw @ m.Dw.T)), 0.01, rtol=0.1)


@pytest.mark.slow
def test_pure_feedthrough(tmp_path, capsys):
    fmu = build_static_fmu(tmp_path, [[1.0]])
    out = tmp_path / "m.toml"
    assert main(["model", str(fmu), "--inputs", "u1", "--outputs", "y1", "-o", str(out)]) == 0
    m = FDIModel.from_file(out)
    assert m.n == 0 and abs(m.Du[0, 0] - 1.0) < 0.02
