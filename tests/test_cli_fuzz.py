"""Seeded fuzzing of the command line (issue 22): no traceback, no hang, no silent change.

Every invocation runs ``fmu_fdi.cli.main`` in this process (a subprocess per call would cost a
second of start-up each; the subprocess path is covered by the CLI tests) under a wall-clock
alarm, with stdout and stderr captured. Its outcome is one of

- ``clean``: a non-zero exit status and a message on stderr, without a traceback;
- ``accepted``: exit status 0;
- ``traceback``: an exception escaped ``main`` or stderr holds a traceback;
- ``hang``: the alarm fired (``HANG_S`` seconds);
- ``silent-wrong``: an invocation that must be refused (a value outside its type or range, an
  output over an input, a name that does not exist) exited 0.

Families: ``simulate``, ``diagnose``, ``plot``, ``build``, ``campaign`` (hostile campaign and
results files), ``model`` (hostile experiment options; refused before the plant runs). Each
family has hand-written hostile cases (every one of issue 22's) and seeded random
combinations of hostile option values. Tracebacks, hangs and silent-wrong must be 0.

Run ``python tests/test_cli_fuzz.py`` for the table per family.
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import random
import signal
import sys
from pathlib import Path

import pytest

SEED = 20261126
RANDOM_PER_FAMILY = 40
HANG_S = int(os.environ.get("CLI_FUZZ_HANG_S", "30"))  # seconds before a call counts as a hang


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


def invoke(argv, timeout=HANG_S) -> tuple[str, int | None, str]:
    """(outcome, exit status, stderr) of ``fmu-fdi ARGV`` in this process (see module docstring)."""
    from fmu_fdi.cli import main

    out, err = io.StringIO(), io.StringIO()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(timeout)
    code = None
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main([str(a) for a in argv])
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 2
    except _Hang:
        return "hang", None, err.getvalue()
    except BaseException as exc:  # noqa: BLE001 - anything escaping main is the finding
        import traceback

        return "traceback", None, err.getvalue() + "".join(traceback.format_exception(exc))
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    text = err.getvalue()
    if "Traceback (most recent call last)" in text:
        return "traceback", code, text
    if code == 0:
        return "accepted", code, text
    return ("clean" if text.strip() else "traceback"), code, text


# ------------------------------------------------------------------------------------ set-up
@pytest.fixture(scope="module")
def ctx(tmp_path_factory):
    return make_context(tmp_path_factory.mktemp("clifuzz"))


def make_context(folder: Path) -> dict:
    """FMUs, a design, a log, a model file and a valid campaign, built once."""
    import plant_fmus

    from fmu_fdi.campaign.example import build_fmus, write_campaign

    folder = Path(folder)
    fmus = build_fmus(folder)
    model = plant_fmus.model_path("dts200")
    design = folder / "dos.json"
    assert invoke(["design", model, "--method", "dos", "--ts", "1", "-o", design])[0] == "accepted"
    from plant_fmus.dts200 import dts200_physics as phys

    _, q = phys.operating_point()
    pumps = folder / "pumps.csv"
    pumps.write_text(f"time,Q1,Q2\n0,{float(q[0])!r},{float(q[1])!r}\n")
    log = folder / "log.csv"
    res = invoke(["simulate", "--plant", fmus["plant"], "--diagnoser", fmus["bank"], "--input", pumps, "--stop", "40",
                  "--step", "1", "--fault", "abrupt:plant.f_sensor_h2:20:2", "-o", log])
    assert res[0] == "accepted", res
    other = folder / "lateral.json"  # a design of another plant
    assert invoke(["design", plant_fmus.model_path("lateral_aircraft"), "--method", "nullspace", "--ts", "0.1",
                   "-o", other])[0] == "accepted"
    camp = write_campaign(folder, "fz", stop=40.0, fault_free=1, targets=("plant.f_sensor_h1",), magnitudes=(1.0,),
                          onset=20.0, rate=0.01, scales=(0.8, 1.6, 3), zone=5.0)
    return {"dir": folder, "plant": fmus["plant"], "bank": fmus["bank"], "model": model, "design": design,
            "log": log, "pumps": pumps, "other": other, "campaign": camp, "campaign_text": camp.read_text(), "n": 0}


def _file(ctx, suffix, content) -> Path:
    ctx["n"] += 1
    p = ctx["dir"] / f"f{ctx['n']}{suffix}"
    p.write_bytes(content if isinstance(content, bytes) else content.encode())
    return p


def _out(ctx, suffix) -> Path:
    ctx["n"] += 1
    return ctx["dir"] / "out" / f"o{ctx['n']}{suffix}"


# ------------------------------------------------------------------------------- the families
HOSTILE_NUMBERS = ["0", "-1", "nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "x", "", "1e12", "4294967303",
                   "9223372036854775808", "1.5"]


def simulate_cases(ctx, rng):
    base = ["simulate", "--plant", ctx["plant"], "--diagnoser", ctx["bank"], "--input", ctx["pumps"]]
    sure = [  # must be refused
        base + ["--stop", "1e308", "--step", "1", "-o", _out(ctx, ".csv")],
        base + ["--stop", "10", "--step", "1e308", "-o", _out(ctx, ".csv")],
        base + ["--stop", "10", "--step", "1", "--param", "plant.seed=4294967303", "-o", _out(ctx, ".csv")],
        base + ["--stop", "10", "--step", "1", "--param", "plant.seed=1.5", "-o", _out(ctx, ".csv")],
        base + ["--stop", "10", "--step", "1", "--param", "plant.noise_enable=no", "-o", _out(ctx, ".csv")],
        base + ["--stop", "10", "--step", "1", "--param", "plant.noise_enable=maybe", "-o", _out(ctx, ".csv")],
        base + ["--stop", "10", "--step", "1", "--param", "plant.noise_enable=2", "-o", _out(ctx, ".csv")],
        base + ["--stop", "10", "--step", "1", "--fault", "abrupt:plant:5:1", "-o", _out(ctx, ".csv")],
        ["simulate", "--plant", ctx["bank"], "--diagnoser", ctx["plant"], "--input", ctx["pumps"], "--stop", "10",
         "--step", "1", "-o", _out(ctx, ".csv")],
    ]
    inp = _file(ctx, ".csv", "time,Q1,Q2\n0,1,1\n10,1,1\n")
    sure.append(["simulate", "--plant", ctx["plant"], "--stop", "10", "--step", "1", "--input", inp, "-o", inp])
    out = [("refuse", a) for a in sure]
    for _ in range(RANDOM_PER_FAMILY):
        a = list(base)  # OPTION=VALUE, so that '-1' reaches the check rather than argparse's option parser
        a += [f"--stop={rng.choice(HOSTILE_NUMBERS + ['10', '20'] * 4)}",
              f"--step={rng.choice(HOSTILE_NUMBERS + ['1'] * 6)}"]
        if rng.random() < 0.4:
            a += [f"--start={rng.choice(HOSTILE_NUMBERS)}"]
        if rng.random() < 0.6:
            name = rng.choice(['seed', 'noise_enable', 'std_h1', 'nosuch'])
            value = rng.choice(HOSTILE_NUMBERS + ['true', 'off', 'True', '3', '0.01'])
            wrong = ((name == "seed" and value not in ("0", "-1", "3", "4294967303", "9223372036854775808"))
                     or (name == "seed" and value in ("4294967303", "9223372036854775808"))
                     or (name == "noise_enable" and value not in ("true", "True"))
                     or (name == "std_h1" and value in ("x", "", "true", "True", "off", "nan")))
            a += [f"--param=plant.{name}={value}"]
            if wrong:  # a value the variable cannot hold exactly: must be refused whatever else is right
                out.append(("refuse", a + ["--stop=10", "--step=1", "-o", _out(ctx, ".csv")]))
                continue
        if rng.random() < 0.4:
            a += ["--fault", f"{rng.choice(['abrupt', 'stuck', 'gain', 'bogus'])}:"
                             f"{rng.choice(['plant.f_sensor_h1', 'plant', 'x.y', '.'])}:"
                             f"{rng.choice(['5', 'nan', '-1', '1e308'])}:{rng.choice(HOSTILE_NUMBERS)}"]
        out.append(("any", a + ["-o", _out(ctx, ".csv")]))
    return out


def diagnose_cases(ctx, rng):
    logs = [b"", b"time\n", b"\x00\x01\x02binary", "time,h1\n0,1\n".encode("utf-16"),
            b"time,Q1,Q2,h1,h2,h3\n0,1,1,1,1\n",
            b"time,Q1,Q2,h1,h2,h3\n0,nan,1,1,1,1\n1,1,1,1,1,1e308\n", b"\xff\xfe\xfa garbage\n"]
    copy = _file(ctx, ".csv", ctx["log"].read_bytes())
    sure = [["diagnose", copy, "--design", ctx["design"], "-o", copy],
            ["diagnose", ctx["log"], "--design", ctx["bank"], "-o", _out(ctx, ".csv")],
            ["diagnose", ctx["log"], "--design", ctx["model"], "-o", _out(ctx, ".csv")]]
    out = [("refuse", a) for a in sure]
    for data in logs:
        out.append(("any", ["diagnose", _file(ctx, ".csv", data), "--design", ctx["design"], "-o", _out(ctx, ".csv")]))
    for _ in range(RANDOM_PER_FAMILY // 2):
        design = json.loads(ctx["design"].read_text())
        key = rng.choice(["signals", "decision", "evaluation", "faults", "thresholds", "format"])
        design[key] = rng.choice([None, 1e308, "x", [], {}, -1])
        out.append(("any", ["diagnose", ctx["log"], "--design", _file(ctx, ".json", json.dumps(design)),
                            "-o", _out(ctx, ".csv")]))
    return out


def plot_cases(ctx, rng):
    sure = [["plot", ctx["log"], "--design", ctx["other"], "-o", _out(ctx, ".png")],
            ["plot", ctx["log"], "-o", ctx["log"]]]
    out = [("refuse", a) for a in sure]
    for data in [b"", b"time\n0\n", b"\x00\x00", b"time,fault_detected,isolated_fault\n0,1,1e308\n",
                 b"time,diagnoser.fault_detected,diagnoser.isolated_fault\n0,0,0\n1,1,-5\n"]:
        out.append(("any", ["plot", _file(ctx, ".csv", data), "-o", _out(ctx, ".png")]))
    return out


def build_cases(ctx, rng):
    sure = [["build", ctx["model"], "-o", _out(ctx, ".fmu")],
            ["build", _file(ctx, ".json", b"\x00binary"), "-o", _out(ctx, ".fmu")],
            ["build", ctx["design"], "-o", ctx["design"]]]
    return [("refuse", a) for a in sure]


CAMPAIGN_EDITS = [
    ("fault_free = 2", "fault_free = 1000000000"),
    ("fault_free = 1", "fault_free = 1000000000"),
    ("seed_base = 1", "seed_base = 9223372036854775807"),
    ("seed_base = 1", "seed_base = 4294967296"),
    ("seed_base = 1", "seed_base = -1"),
    ('target = ["plant.f_sensor_h1"]', 'target = ["plant"]'),
    ('target = ["plant.f_sensor_h1"]', 'target = ["f_sensor_h1"]'),
    ("magnitude = [1.0]", "magnitude = [true, false]"),
    ("magnitude = [1.0]", "magnitude = [1e308]"),
    ("magnitude = [1.0]", "magnitude = [-1e308, 1e308]"),
    ("count = 3", "count = 1000000000"),
    ("step = 1.0", "step = 1e308"),
    ("stop = 40.0", "stop = 1e308"),
    ("APPEND", "\n[sample.parameters]\n\"plant.std_h1\" = [" + ",".join(["0.1"] * 2000) + "]\n"
               "\"plant.std_h2\" = [" + ",".join(["0.1"] * 2000) + "]\n"),
    ("[parameters]", "[parameters]\n\"plant.seed\" = 4294967303"),
    ("[parameters]", "[parameters]\n\"plant.noise_enable\" = \"no\""),
    ("[parameters]", "[parameters]\n\"plant.noise_enable\" = 1"),
    ("confidence = 0.95", "confidence = nan"),
    ("confidence = 0.95", "confidence = true"),
    ("APPEND", "\n[labels]\n\"plant.f_sensor_h9\" = \"sensor_h9\"\n"),
]
MUST_REFUSE_EDIT = {0, 1, 2, 3, 4, 5, 6, 7, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19}


def campaign_cases(ctx, rng):
    text = ctx["campaign_text"]
    out = []
    def edit(body, i):
        """(edited body, whether the edit applied)."""
        a, b = CAMPAIGN_EDITS[i]
        if a == "APPEND":
            return body + b, True
        return body.replace(a, b, 1), a in body

    for i, (a, b) in enumerate(CAMPAIGN_EDITS):
        if a not in text and a != "APPEND":
            continue
        path = _file(ctx, ".toml", edit(text, i)[0])
        out.append(("refuse" if i in MUST_REFUSE_EDIT else "any", ["campaign", path, "-o", _out(ctx, "")]))
    for _ in range(RANDOM_PER_FAMILY):  # two edits at once
        picks = rng.sample(range(len(CAMPAIGN_EDITS)), 2)
        body, expect = text, "any"
        for i in picks:
            body, applied = edit(body, i)
            if applied and i in MUST_REFUSE_EDIT:
                expect = "refuse"
        out.append((expect, ["campaign", _file(ctx, ".toml", body), "-o", _out(ctx, "")]))
    deep = "format = \"fmu-fdi-campaign/1\"\nx = " + "[" * 5000 + "]" * 5000 + "\n"
    for data in [b"\x00\x01binary", text.encode("utf-16"), deep.encode(), b"\xff\xfe\xfd", b"",
                 b"format = 1\n", b"[a]\nb = {c = {d = [1, 2, {e = 3}]}}\n"]:
        out.append(("refuse", ["campaign", _file(ctx, ".toml", data), "-o", _out(ctx, "")]))
    path = ctx["campaign"]
    out += [("refuse", ["campaign", path, "-o", _out(ctx, ""), "--workers", w]) for w in ("0", "-3")]
    out.append(("refuse", ["campaign", path, "-o", _out(ctx, ""), "--scheduler", ""]))
    header = json.dumps({"format": "fmu-fdi-campaign-results/1", "campaign": "fz", "runs": 2})
    for line in ["42", "[]", "{}", '{"run": 1, "status": "ok"}', '{"run": {"index": 0, "key": 5}, "status": "ok"}',
                 '{"run": {"index": 0, "key": "k", "fault": null}, "status": "ok", "diagnosers": 3}']:
        folder = _out(ctx, "")
        folder.mkdir(parents=True)
        (folder / "runs.jsonl").write_text(header + "\n" + line + "\n" + '{"x": 1}\n')
        out.append(("refuse", ["campaign", path, "-o", folder, "--resume"]))
    folder = _out(ctx, "")
    folder.mkdir(parents=True)
    (folder / "runs.jsonl").write_bytes(header.encode() + b"\n\xff\xfe{}\n{}\n")
    out.append(("refuse", ["campaign", path, "-o", folder, "--resume"]))
    return out


def model_cases(ctx, rng):
    base = ["model", ctx["plant"], "--method", "identify", "--inputs", "Q1", "Q2", "--outputs", "h1", "h2", "h3"]
    sure = [["--ts", "0"], ["--ts", "nan"], ["--ts", "inf"], ["--ts", "-1"], ["--settle", "1e12"],
            ["--settle", "nan"], ["--settle", "-5"], ["--seed", "-1"], ["--seed", str(2 ** 70)], ["--min-fit", "nan"],
            ["--min-fit", "inf"], ["--min-fit", "101"], ["--samples", "0"], ["--samples", "1000000000000"],
            ["--period", "0"], ["--at", "uu=5"], ["--amplitude", "x=1"], ["--order", "-1"], ["--order", "-2"]]
    out = [("refuse", base + extra + ["-o", _out(ctx, ".toml")]) for extra in sure]
    return out


FAMILIES = {"simulate": simulate_cases, "diagnose": diagnose_cases, "plot": plot_cases, "build": build_cases,
            "campaign": campaign_cases, "model": model_cases}


def fuzz(ctx, seed=SEED, verbose=False) -> dict:
    """{family: {outcome: count, "tries": n, "findings": [...]}}."""
    rng = random.Random(seed)
    table = {}
    for family, cases in FAMILIES.items():
        row = {"tries": 0, "clean": 0, "accepted": 0, "traceback": 0, "hang": 0, "silent-wrong": 0, "findings": []}
        for expect, argv in cases(ctx, rng):
            outcome, code, err = invoke(argv)
            if outcome == "accepted" and expect == "refuse":
                outcome = "silent-wrong"
            row["tries"] += 1
            row[outcome] += 1
            if outcome in ("traceback", "hang", "silent-wrong"):
                row["findings"].append((outcome, [str(a)[:80] for a in argv[:1] + argv[-6:]], err.strip()[-300:]))
            elif verbose and outcome == "clean":
                print(f"  {family}: {err.strip().splitlines()[-1][:160] if err.strip() else ''}")
        table[family] = row
    return table


def test_cli_fuzz_no_traceback_hang_or_silent_change(ctx):
    table = fuzz(ctx)
    findings = [(f, x) for f, row in table.items() for x in row["findings"]]
    assert not findings, "\n".join(f"{f}: {x}" for f, x in findings)
    assert sum(row["clean"] for row in table.values()) > 60


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        c = make_context(Path(tmp))
        result = fuzz(c, verbose="-v" in sys.argv)
    print(f"{'family':<10} tries  clean  accepted  tracebacks  hangs  silent-wrong")
    for fam, row in result.items():
        print(f"{fam:<10} {row['tries']:5d}  {row['clean']:5d}  {row['accepted']:8d}  {row['traceback']:10d}  "
              f"{row['hang']:5d}  {row['silent-wrong']:12d}")
    for fam, row in result.items():
        for outcome, argv, err in row["findings"]:
            print(f"\n[{fam}] {outcome}: {' '.join(argv)}\n    {err.splitlines()[-1] if err else ''}")
