"""An FMI 3 model-exchange FMU with array variables, compiled from C with gcc (me_fmus' linear
plant x' = A x + B u, y = C x + D u behind an array-aware glue).

Value references: 0 the state array ``x`` (3 elements), 1 its derivative ``der(x)``, then the
inputs ``u1``, ``u2`` and the outputs: scalars ``y1``, ``y2`` or, with ``array_output=True``,
one array ``y`` of 2 elements. ``fmi3GetFloat64``/``fmi3SetFloat64`` read and write an array
variable's elements in order (FMI 3.0 sec. 2.2.6.1, nValues = the elements of all vrs).
"""
from __future__ import annotations

import itertools
import shutil
import subprocess
import uuid
import zipfile
from pathlib import Path

import me_fmus

_serial = itertools.count()

ARRAY_GLUE = r"""
static const unsigned BASE[] = %(base)s, SIZE[] = %(size)s;
#define NVR (sizeof BASE / sizeof BASE[0])
fmi3Status fmi3GetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    size_t at = 0;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= NVR) return fmi3Error;
        for (unsigned j = 0; j < SIZE[vr[k]]; j++) {
            if (at >= nv || get1(i, BASE[vr[k]] + j, &v[at])) return fmi3Error;
            at++;
        }
    }
    return at == nv ? fmi3OK : fmi3Error;
}
fmi3Status fmi3SetFloat64(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t nv) {
    size_t at = 0;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= NVR) return fmi3Error;
        for (unsigned j = 0; j < SIZE[vr[k]]; j++) {
            if (at >= nv || set1(i, BASE[vr[k]] + j, v[at])) return fmi3Error;
            at++;
        }
    }
    return at == nv ? fmi3OK : fmi3Error;
}
"""


def _glue3() -> str:
    """me_fmus' FMI 3 glue without its scalar Get/SetFloat64 (ARRAY_GLUE replaces them)."""
    glue = me_fmus.GLUE3
    start = glue.index("fmi3Status fmi3GetFloat64(")
    end = glue.index("fmi3Status fmi3GetDirectionalDerivative(")
    return glue[:start] + glue[end:]


def build_array_fmu(tmp_path, array_output: bool = False) -> Path:
    """Compile the linear plant with an array state (and optionally an array output) as an FMI 3 ME FMU."""
    import fmpy

    p = me_fmus.PLANTS["linear"]
    nx, nu, ny = p["nx"], p["nu"], p["ny"]
    mid = f"arr{next(_serial)}"
    token = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, mid)) + "}"
    work = Path(tmp_path) / mid
    (work / "sources").mkdir(parents=True)
    # flat indices of me_fmus' core: x 0.., der(x) nx.., u 2nx.., y 2nx+nu..
    base = [0, nx] + [2 * nx + j for j in range(nu)]
    size = [nx, nx] + [1] * nu
    if array_output:
        base, size = base + [2 * nx + nu], size + [ny]
    else:
        base, size = base + [2 * nx + nu + i for i in range(ny)], size + [1] * ny
    fmt = dict(p, header="fmi3Functions.h", token=token,
               x_start="{" + ", ".join(map(repr, map(float, p["x_start"]))) + "}",
               u_start="{" + ", ".join(map(repr, map(float, p["u_start"]))) + "}",
               base="{" + ", ".join(map(str, base)) + "}", size="{" + ", ".join(map(str, size)) + "}")
    (work / "sources" / "model.c").write_text(me_fmus.CORE % fmt + _glue3() % fmt + ARRAY_GLUE % fmt)
    (work / "sources" / "unused.c").write_text(
        "\n".join(f"int {name}(void) {{ return 3; }}" for name in me_fmus.UNUSED3) + "\n")
    binary = work / "binaries" / fmpy.platform_tuple / f"{mid}.so"
    binary.parent.mkdir(parents=True)
    subprocess.run([shutil.which("gcc") or "gcc", "-std=c99", "-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-Werror",
                    "-Wno-unused-parameter", "-I", str(Path(fmpy.__file__).parent / "c-code"),
                    str(work / "sources" / "model.c"), str(work / "sources" / "unused.c"), "-lm", "-o", str(binary)],
                   check=True, capture_output=True, text=True)
    xs = " ".join(map(repr, map(float, p["x_start"])))
    rows = ['<Float64 name="time" valueReference="999" causality="independent" variability="continuous"/>',
            f'<Float64 name="x" valueReference="0" causality="local" variability="continuous" initial="exact" '
            f'start="{xs}"><Dimension start="{nx}"/></Float64>',
            f'<Float64 name="der(x)" valueReference="1" causality="local" variability="continuous" derivative="0">'
            f'<Dimension start="{nx}"/></Float64>']
    rows += [f'<Float64 name="u{j + 1}" valueReference="{2 + j}" causality="input" variability="continuous" '
             f'start="{p["u_start"][j]}"/>' for j in range(nu)]
    if array_output:
        rows.append(f'<Float64 name="y" valueReference="{2 + nu}" causality="output" variability="continuous">'
                    f'<Dimension start="{ny}"/></Float64>')
        outs = [2 + nu]
    else:
        rows += [f'<Float64 name="y{i + 1}" valueReference="{2 + nu + i}" causality="output" '
                 f'variability="continuous"/>' for i in range(ny)]
        outs = [2 + nu + i for i in range(ny)]
    struct = ("".join(f'<Output valueReference="{k}"/>' for k in outs) + '<ContinuousStateDerivative valueReference="1"/>'
              + "".join(f'<InitialUnknown valueReference="{k}"/>' for k in [1] + outs))
    (work / "modelDescription.xml").write_text(
        f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="3.0" modelName="{mid}" '
        f'instantiationToken="{token}">\n<ModelExchange modelIdentifier="{mid}" providesDirectionalDerivatives="false"/>\n'
        f'<ModelVariables>\n' + "\n".join(rows) + f'\n</ModelVariables>\n<ModelStructure>{struct}</ModelStructure>\n'
        f'</fmiModelDescription>\n')
    fmu = Path(tmp_path) / f"{mid}.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        for path in sorted(work.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(work).as_posix())
    return fmu
