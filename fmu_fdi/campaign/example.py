"""The example campaign: the DTS200 three-tank plant FMU with a dedicated observer bank for its
level sensors (three residuals, rms over 20 s, the analytic threshold of a 1e-4 false-alarm
probability per sample for the 0.1 cm sensor noise, persistence 3 of 5), the pumps at their
operating flows, Jacobi order. It serves the tests, the benchmark (benchmarks/campaign_speed.py)
and as a template for a campaign file: ``fmu-fdi campaign --example DIR`` (or ``python -m
fmu_fdi.campaign.example DIR``) writes ``DIR/dts200.toml`` and the FMUs it runs.
"""
from __future__ import annotations

import shutil
from pathlib import Path

TEMPLATE = """\
format = "fmu-fdi-campaign/1"
name = "{name}"

[simulation]
step = 1.0
stop = {stop}
order = "jacobi"

[fmus]
plant = "dts200.fmu"
bank = "dts200_sensor_dos.fmu"
{extra_fmus}

[inputs]
time = [0.0]

[inputs.values]
Q1 = [{q1!r}]
Q2 = [{q2!r}]

[parameters]
{parameters}

[sample]
method = "grid"
fault_free = {fault_free}
replicates = {replicates}
seeds = ["plant.seed"]
seed_base = {seed_base}

[sample.fault]
kind = ["abrupt"]
target = {targets}
magnitude = {magnitudes}
onset = [{onset}]

[analysis]
confidence = 0.95
false_alarm_rate = {rate}
scales = {{ min = {scale_min}, max = {scale_max}, count = {scale_count} }}
zone_start = {zone}
"""


def build_fmus(folder, native: bool = False) -> dict:
    """Build the plant FMU and the bank's diagnostic FMU into ``folder``; ``{instance: path}``.

    ``native``: both as C FMUs (the native plant, docs/native-plants.md, and the native
    diagnoser), under the same file names, so a campaign runs without Python in the FMUs."""
    import numpy as np
    import plant_fmus

    from ..design import dedicated_bank
    from ..diagnoser import Diagnoser
    from ..evaluation import analytic_threshold
    from ..fmu import build_fmu
    from ..model import FDIModel

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    plant = plant_fmus.build("dts200", folder)
    model = FDIModel.from_file(plant_fmus.model_path("dts200"))
    bank = dedicated_bank(model.discretize(1.0), "sensor", noise="ignore")
    evaluation = {"kind": "rms", "window": 20}
    # w is unit white noise in the model (Dw carries the 0.1 cm): the exact rms threshold at 1e-4
    th = [analytic_threshold(bank, evaluation, 1e-4, noise_cov=np.eye(model.nw), group=i)
          for i in range(len(bank.groups))]
    dg = Diagnoser(bank, evaluation=evaluation, thresholds=th, decision={"persistence": [3, 5]},
                   name="dts200_sensor_dos")
    if native:
        from plant_fmus.native_build import build_native

        native_plant = build_native("dts200", folder / "native", reference=plant)
        plant = Path(native_plant.replace(plant))
        shutil.rmtree(folder / "native", ignore_errors=True)
    return {"plant": plant, "bank": build_fmu(dg, folder / "dts200_sensor_dos.fmu",
                                              target="native" if native else "pythonfmu")}


def write_campaign(folder, name="dts200-dos", *, stop=1000.0, fault_free=2, replicates=1, seed_base=1,
                   targets=("plant.f_sensor_h1", "plant.f_sensor_h2", "plant.f_sensor_h3"),
                   magnitudes=(0.5, 1.0), onset=None, rate=1e-3, scales=(0.5, 2.0, 16), zone=50.0,
                   extra_fmus=None, parameters=None) -> Path:
    """Write ``folder/<name>.toml`` next to FMUs built by :func:`build_fmus` (``extra_fmus``:
    more ``{instance: file}`` in that folder, e.g. another diagnoser; ``parameters``: set in every
    run); returns its path."""
    import json

    from plant_fmus.dts200 import dts200_physics as phys

    _, q = phys.operating_point()
    text = TEMPLATE.format(
        name=name, stop=float(stop), q1=float(q[0]), q2=float(q[1]), fault_free=fault_free, replicates=replicates,
        seed_base=seed_base, targets=json.dumps(list(targets)), magnitudes=[float(m) for m in magnitudes],
        onset=float(onset if onset is not None else stop / 2), rate=rate, scale_min=scales[0],
        scale_max=scales[1], scale_count=scales[2], zone=float(zone),
        extra_fmus="\n".join(f"{k} = {json.dumps(str(v))}" for k, v in (extra_fmus or {}).items()),
        parameters="\n".join(f"{json.dumps(k)} = {v!r}" for k, v in (parameters or {}).items()))
    path = Path(folder) / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def write_example(folder) -> int:
    """``fmu-fdi campaign --example DIR``: the example campaign and its FMUs, with one line per
    file written."""
    from ..outpath import check_output_path

    check_output_path(Path(folder) / "dts200.toml", (".toml",), "example campaign")
    fmus = build_fmus(folder)
    path = write_campaign(folder, "dts200")
    for p in (*fmus.values(), path):
        print(f"wrote {p}")
    print(f"run it: fmu-fdi campaign {path} -o results")
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(write_example(sys.argv[1] if len(sys.argv) > 1 else "campaign"))
