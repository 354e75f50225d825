"""Seeded fuzzing of design and model files (issue 12 item 3): no input may crash a loader.

A mutator applies 1-3 hostile edits to valid design dicts and model dicts (replace any
node with NaN/Inf/null/huge/string/Boolean/deep nesting, delete or add keys, grow or
shrink lists, scale numbers by 0, -1, 1e10, NaN) and flips, inserts or truncates bytes
of the files. Every try must end in the project's clean error types (``ModelError``,
which ``DesignFileError`` is, or ``DesignError``) or be accepted; an accepted design must
then run (three samples through the run-time), an accepted model must round-trip.
Anything else is a crash; crashes must be 0.

Run ``python tests/test_fuzz_inputs.py [TRIES]`` for a longer campaign with the figures.
"""
from __future__ import annotations

import copy
import json
import math
import random
import sys
import tempfile
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import published as pub  # noqa: E402
from fmu_fdi import Diagnoser, FDIModel, component_fault, parametric_fault, sensor_fault  # noqa: E402
from fmu_fdi.designfile import load_design, validate_design  # noqa: E402
from fmu_fdi.errors import DesignError, ModelError  # noqa: E402
from fmu_fdi.runtime.engine import DiagnoserRuntime  # noqa: E402

CLEAN = (ModelError, DesignError)
SEED = 20261123
TRIES = 1500  # per corpus kind in CI (dicts); byte-level tries are a fifth of that

_deep = []
for _ in range(200):  # deeper than any file needs (the loaders allow 64), shallow enough to copy
    _deep = [_deep]
HOSTILE = [None, True, False, 0, -1, 1, 0.5, -0.5, 2.5, 1e308, -1e308, 1e150, 10**400, -(10**30), math.nan,
           math.inf, -math.inf, "", "0.5", "1e-3", "x", "sensor", [], [[]], [1, 2], [[1.0, 2.0], [3.0]],
           [[math.nan]], [[1e300]], {}, {"kind": "rms"}, {"kind": "bogus"}, 10**10, 100_000, 100_001,
           [0, 10**9], _deep]


def _paths(node, path=()):
    yield path
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, path + (i,))


def _get(node, path):
    for p in path:
        node = node[p]
    return node


def mutate(doc, rng: random.Random):
    """1-3 hostile edits of a JSON-like document (a deep copy)."""
    doc = copy.deepcopy(doc)
    for _ in range(rng.randint(1, 3)):
        paths = list(_paths(doc))
        path = rng.choice(paths[1:]) if len(paths) > 1 else ()
        if not path:
            return rng.choice(HOSTILE)
        parent, key = _get(doc, path[:-1]), path[-1]
        op = rng.random()
        if op < 0.5:
            parent[key] = copy.deepcopy(rng.choice(HOSTILE))
        elif op < 0.6:
            del parent[key]
        elif op < 0.7 and isinstance(parent, dict):
            parent[rng.choice(["extra", "windwo", "kind", "name", "dt", "valid_range"])] = rng.choice(HOSTILE)
        elif op < 0.8 and isinstance(parent[key], list):
            lst = parent[key]
            if lst and rng.random() < 0.5:
                lst.pop(rng.randrange(len(lst)))
            else:
                lst.append(copy.deepcopy(rng.choice(lst)) if lst else rng.choice(HOSTILE))
        elif isinstance(parent[key], float) or type(parent[key]) is int and abs(parent[key]) < 2**60:
            parent[key] = parent[key] * rng.choice([0, -1, 10**10, 1e-10, math.nan])
        else:
            parent[key] = copy.deepcopy(rng.choice(HOSTILE))
    return doc


def mutate_bytes(data: bytes, rng: random.Random) -> bytes:
    b = bytearray(data)
    op = rng.random()
    if op < 0.4:
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
    elif op < 0.6:
        b = b[: rng.randrange(len(b))]
    elif op < 0.8:
        i = rng.randrange(len(b))
        b[i:i] = bytes(rng.choice([b"\x00", b"\xff\xfe", b"[" * 2000, b"NaN", b"1e999", b"9" * 400, b'"x"']))
    else:
        b = bytearray(data.decode("utf-8").encode(rng.choice(["utf-16", "utf-32", "latin-1"])))
    return bytes(b)


def design_corpus() -> list[dict]:
    from fmu_fdi.design.problems.nullspace import nullspace_design
    from fmu_fdi.design.problems.rls import rls_estimator

    m = pub.three_tank_like()
    m = FDIModel.from_matrices(m.A, m.Bu, m.C, u_names=m.u_names, y_names=m.y_names,
                               faults=[sensor_fault("s1", m.y_names[0]), sensor_fault("s2", m.y_names[1])])
    gen = nullspace_design(m)
    lti = Diagnoser(gen, Ts=0.1, thresholds=1.0, decision={"persistence": [2, 3], "latch": True}).design
    n = len(lti["evaluation"])
    stat = Diagnoser(gen, Ts=0.1, evaluation=[{"kind": "cusum", "delta": 1.0, "sigma": 0.5}] * n,
                     thresholds=5.0).design
    maj = copy.deepcopy(lti)
    maj["evaluation"][0]["threshold"] = {"kind": "majorant", "J0": 0.1, "taps": [1.0, 0.5], "tail": 0.1}
    maj["evaluation"][-1]["threshold"] = {"kind": "adaptive", "J0": 0.1, "a": 2.0,
                                          "evaluation": {"kind": "rms", "window": 5}}
    arx = FDIModel.from_matrices([[0.5]], [[1.0]], [[1.0]], dt=0.1, faults=[sensor_fault("s", "y0")])
    rls = Diagnoser(rls_estimator(arx), thresholds={"kind": "fixed", "value": 4.0}).design
    return [json.loads(json.dumps(d)) for d in (lti, stat, maj, rls)]


def model_corpus() -> list[dict]:
    m = pub.three_tank_like()
    full = FDIModel.from_matrices(m.A, m.Bu, m.C, Bd=m.Bd, u_names=m.u_names, y_names=m.y_names,
                                  d_names=m.d_names, units={"h1": "cm"},
                                  operating_point={"u": [21.37, 53.8], "y": [41, 32, 36.6]},
                                  faults=m.faults + [component_fault("leak1", [[-0.01], [0], [0]]),
                                                     parametric_fault("clog", dA=0.1 * np.eye(3))], name="t")
    disc = pub.three_tank_like(dt=0.5)
    return [json.loads(json.dumps(x.to_dict())) for x in (full, disc)]


def _use_design(d) -> None:
    validate_design(d, "fuzz")
    Diagnoser.from_design(d)  # what Diagnoser.load does with it (rebuilds the generator from the model)
    rt = DiagnoserRuntime(d)
    rng = np.random.default_rng(0)
    for _ in range(3):
        rt.step(rng.standard_normal(rt.nu).tolist(), rng.standard_normal(rt.ny).tolist())


def _use_model(d) -> None:
    m = FDIModel.from_dict(d, "fuzz")
    FDIModel.from_dict(json.loads(json.dumps(m.to_dict())), "again")


def _try(fn, arg, counts: dict, label: str) -> None:
    counts["tries"] += 1
    try:
        fn(arg)
    except CLEAN:
        counts["clean errors"] += 1
    except Exception:  # noqa: BLE001 -- anything else is what the fuzzer hunts
        counts["crashes"] += 1
        if len(counts["examples"]) < 5:
            counts["examples"].append(f"{label}: {traceback.format_exc(limit=3)}")
    else:
        counts["accepted"] += 1


def fuzz(tries: int = TRIES, seed: int = SEED) -> dict:
    """Run the campaign; returns counts per target and in total."""
    rng = random.Random(seed)
    designs, models = design_corpus(), model_corpus()
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for target, corpus, use, load, suffix in (
                ("design dicts", designs, _use_design, lambda p: _use_design(load_design(p)), ".json"),
                ("model dicts", models, _use_model, lambda p: FDIModel.from_file(p), ".toml")):
            counts = {"tries": 0, "clean errors": 0, "accepted": 0, "crashes": 0, "examples": []}
            for i in range(tries):
                _try(use, mutate(rng.choice(corpus), rng), counts, f"{target} #{i}")
            out[target] = counts
            counts = {"tries": 0, "clean errors": 0, "accepted": 0, "crashes": 0, "examples": []}
            for i in range(tries // 5):
                doc = rng.choice(corpus)
                if suffix == ".toml":
                    p = FDIModel.from_dict(doc).to_file(tmp / f"m{i % 2}.toml")
                else:
                    p = tmp / "d.json"
                    p.write_text(json.dumps(doc))
                p.write_bytes(mutate_bytes(p.read_bytes(), rng))
                _try(load, p, counts, f"{target} file bytes #{i}")
            out[target.replace("dicts", "file bytes")] = counts
    return out


def test_fuzz_design_and_model_files_never_crash():
    res = fuzz()  # quiet in the suite: `python tests/test_fuzz_inputs.py` prints the figures
    crashes = [e for c in res.values() for e in c["examples"]]
    assert sum(c["crashes"] for c in res.values()) == 0, "\n".join(crashes)
    # the mutator must reach both outcomes, or it tests nothing
    assert all(c["clean errors"] > 0 for c in res.values())
    assert res["design dicts"]["accepted"] > 0 and res["model dicts"]["accepted"] > 0


if __name__ == "__main__":
    res = fuzz(int(sys.argv[1]) if len(sys.argv) > 1 else TRIES)
    for target, c in res.items():
        print(f"{target}: {c['tries']} tries, {c['clean errors']} clean errors, {c['accepted']} accepted, "
              f"{c['crashes']} crashes")
        for e in c["examples"]:
            print(e)
