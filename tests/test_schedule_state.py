"""Scheduled designs under the runtime rules of issues 21/22 (docs/semantics.md §8, §10, §12), in
both runtimes:

- an overflow in one member only (its residual scaled by 1e140) is that member's fault evidence:
  the shown outputs get ``numeric_reset`` and ``input_invalid``, the other members' diagnoses are
  untouched (judged against each member run alone), and the schedule still moves on the sample
  (its scheduling values are valid, §3); the native FMUs equal the Python schedule on it;
- a scheduled FMU state is accepted only if a run can produce it: every member's state valid for
  that member, the active member -1..K-1 (>= 0 only after a valid sample), the members at one
  step, one threshold_scale and one sample count (they run on the same calls), the outputs the
  composed ones. Python: edits of a real run's state; native: images whose members come from
  different moments of one run, resealed (the checksum recomputed) so that the runtime's own
  validation decides; a bit-flip fuzz of the scheduled image;
- both scheduled FMUs log the same warnings as plain ones and refuse a bad threshold_scale;
- ``active_member`` is reserved: no plain design may name a signal so.
"""
import copy
import json
import math
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmu_fdi import build_fmu
from fmu_fdi.modelset import ModelSet
from fmu_fdi.runtime.design_check import DesignCheckError, check_design
from fmu_fdi.runtime.engine import INPUT_INVALID, NUMERIC_RESET, DiagnoserRuntime, output_type
from fmu_fdi.runtime.schedule import ScheduledRuntime
from native_scenario import compare, python_outputs
from test_schedule import TS, _design, _member
from test_schedule_native import _scenario

RUNNER = Path(__file__).parent / "native_fmu_runner.py"
BIG = 1e140  # member 3's residual gain (the design check allows |x| <= 1e150): r^2 overflows above ~1e14
GLITCH = 1e20  # a finite y deviation only member 3 overflows on: (1e140 * 1e20)^2 > DBL_MAX, (1e20)^2 is not


@pytest.fixture(scope="module")
def design():
    """Three members (u0 = 1, 2, 3); member 3's residual rows scaled by BIG, so a sample 1e20 away
    overflows member 3's rms evaluation only."""
    mset = ModelSet([_member(1.0 + 0.5 * k, float(k + 1)) for k in range(3)], ["u0"])
    d = json.loads(json.dumps(_design(mset, hysteresis=0.3).design))
    gen = d["members"][2]["generator"]
    for g in (gen["discrete"], gen.get("continuous")):  # both realisations: the same filter
        if g:
            g["C"] = [[BIG * x for x in row] for row in g["C"]]
            g["D"] = [[BIG * x for x in row] for row in g["D"]]
    return d


def _ops(n=240):
    """Member 1's region, a glitch of GLITCH on y0 at call 60 while u jumps to member 2's point,
    then the scheduling sweep of test_schedule_native (switches, NaN burst, 1e300, odd steps)."""
    ops = [["step", [1.0], [1.0, 1.0], TS] for _ in range(60)]
    ops += [["step", [2.0], [1.0 + GLITCH, 1.0], TS]] + [["step", [2.0], [1.0, 1.0], TS] for _ in range(20)]
    tail = [op for op in _scenario(np.random.default_rng(3), 1500)[:n] if op[0] != "reset"]
    return ops + tail


def test_an_overflow_in_one_member_is_its_evidence_and_the_schedule_moves(design):
    rt = ScheduledRuntime(design)
    alone = [DiagnoserRuntime(m) for m in design["members"]]  # each member on its own: the reference
    am = rt.names.index("active_member")  # inserted before fault_detected (§12)
    warm = [np.asarray(M, float) for M in design["schedule"]["warm"]]
    for k, op in enumerate(_ops()[:81]):
        if k == 0:  # §12 step 2 for the members alone: x_k = M_k [y - y0_k; u - u0_k] (numpy)
            for m, M, md in zip(alone, warm, design["members"]):
                op0 = md["operating_point"]
                v = np.r_[np.subtract(op[2], op0["y"]), np.subtract(op[1], op0["u"])]
                m.generator.set_state({"x": (M @ v).tolist()})
        out = rt.advance(op[1], op[2], op[3])
        ref = [m.advance(op[1], op[2], op[3]) for m in alone]
        if k == 60:  # the glitch: member 3 alone overflowed (§8), its sample is discarded
            assert [r[NUMERIC_RESET] for r in ref] == [0.0, 0.0, 1.0]
            assert out[NUMERIC_RESET] == 1.0 and out[INPUT_INVALID] == 1.0  # the shown flags: any member's
            assert rt.active == 1  # u = 2: member 2, the schedule is not held by an overflow
        else:
            assert out[NUMERIC_RESET] == 0.0 and out[INPUT_INVALID] == 0.0
        shown = ref[rt.active]
        # every other output is the active member's own (member 2 never saw an overflow); to rounding:
        # numpy's product M v need not sum in index order (a few roundings of O(1) values, carried
        # through a stable filter: 1e-12, relative above 1, is a wide margin)
        assert np.allclose(out[:am], shown[:am], rtol=1e-12, atol=1e-12), k
        assert out[am + 1:am + 3] == shown[am:am + 2] and out[am] == rt.active + 1
    assert rt.members[2].n_numeric_resets == 1 and rt.members[0].n_numeric_resets == 0


def test_native_fmus_equal_the_python_schedule_on_a_one_member_overflow(design, tmp_path):
    ops = _ops()
    rt = ScheduledRuntime(design)
    ref = python_outputs(design, ops, rt)
    jobs = [{"fmu": str(build_fmu(design, tmp_path / f"s{v}.fmu", target="native", fmi_version=v)), "fmi": v,
             "ops": ops} for v in (2, 3)]
    (tmp_path / "jobs.json").write_text(json.dumps(jobs), encoding="utf-8")
    proc = subprocess.run([sys.executable, str(RUNNER), str(tmp_path / "jobs.json"), str(tmp_path / "res.json")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    types = [output_type(n) for n in rt.names]
    for v, res in zip((2, 3), json.loads((tmp_path / "res.json").read_text(encoding="utf-8"))):
        worst, bad = compare(rt.names, types, ref, res["outputs"], rtol=1e-12)  # docs/semantics.md §1
        assert not bad, f"FMI {v}:\n" + "\n".join(bad)
    assert ref[60][NUMERIC_RESET] == ref[60][INPUT_INVALID] == 1.0


# ----------------------------------------------------------------- Python: state validation
@pytest.fixture(scope="module")
def run(design):
    """A runtime after the scenario, and the states it passed (every 5th call)."""
    rt = ScheduledRuntime(design)
    states = []
    for k, op in enumerate(_ops()):
        if op[0] == "step":
            try:
                rt.advance(op[1], op[2], op[3])
            except ValueError:  # a refused step changes nothing
                pass
        elif op[0] == "scale":
            rt.set_threshold_scale(op[1])
        if k % 5 == 0:
            states.append(copy.deepcopy(rt.get_state()))
    return rt, states


def test_every_state_of_a_run_is_accepted(design, run):
    _, states = run
    fresh = ScheduledRuntime(design)
    assert {s["active"] for s in states} >= {0, 1, 2}
    for s in states:
        fresh.set_state(copy.deepcopy(s))
        assert fresh.get_state() == s


def _edit(state, path, value):
    s = copy.deepcopy(state)
    node = s
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return s


def test_states_no_run_produces_are_refused_and_change_nothing(design, run):
    rt, states = run
    early, late = states[12], states[30]
    assert early["members"][0]["n_samples"] != late["members"][0]["n_samples"]
    K = len(design["members"])
    cases = {
        "active member": [_edit(late, ["active"], K), _edit(late, ["active"], -2), _edit(late, ["active"], True),
                          _edit(late, ["active"], 1.0)],
        "member states": [_edit(late, ["members"], late["members"][:-1])],
        "member 3": [_edit(late, ["members", 2, "n_samples"], -1)],
        # each member's state is a valid one, but from another call: a run cannot mix them
        "same calls": [_edit(late, ["members", 1], early["members"][1]),
                       _edit(late, ["members", 2, "threshold_scale"], 2.0 * late["members"][2]["threshold_scale"])],
        "outputs": [_edit(late, ["outputs", INPUT_INVALID], 1.0 - late["outputs"][INPUT_INVALID]),
                    _edit(late, ["outputs", rt.names.index("active_member")], late["active"] + 2.0),
                    _edit(late, ["outputs"], late["outputs"][:-1])],
    }
    fresh = ScheduledRuntime(design).get_state()  # after a reset: no valid sample, no member active
    am = rt.names.index("active_member")
    cases["before any valid sample"] = [_edit(_edit(fresh, ["active"], 0), ["outputs", am], 1.0)]
    target = ScheduledRuntime(design)
    target.set_state(copy.deepcopy(early))
    before = copy.deepcopy(target.get_state())
    for match, bad in cases.items():
        for s in bad:
            with pytest.raises(ValueError, match=match):
                target.set_state(s)
            assert target.get_state() == before  # nothing changed


def test_threshold_scale_is_one_rule_for_every_member(design):
    rt = ScheduledRuntime(design)
    rt.set_threshold_scale(2.0)
    for bad in (-1.0, math.nan, math.inf, "2"):
        with pytest.raises(ValueError, match="threshold_scale"):
            rt.set_threshold_scale(bad)
    assert [m.threshold_scale for m in rt.members] == [2.0] * len(rt.members)


def test_active_member_is_a_reserved_name(design):
    d = copy.deepcopy(design["members"][0])
    d["signals"]["u"] = ["active_member"]
    with pytest.raises(DesignCheckError, match="active_member"):
        check_design(d)


# ----------------------------------------------------------------- native: state validation
PROBE = r'''
import json, sys
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

spec = json.load(open(sys.argv[1]))
md = read_model_description(spec["fmu"])
fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(spec["fmu"]), modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName="probe")
fmu.instantiate()
fmu.setupExperiment(startTime=0.0)
fmu.enterInitializationMode()
fmu.exitInitializationMode()
ins = [v.valueReference for v in md.modelVariables if v.causality == "input"]
active = [v.valueReference for v in md.modelVariables if v.name == "active_member"]
out, t = {"saved": {}, "tried": []}, 0.0
if -1 in spec["save_at"]:  # the state before the first step
    out["saved"]["-1"] = fmu.serializeFMUstate(fmu.getFMUstate()).hex()
for k, op in enumerate(spec["ops"]):
    fmu.setReal(ins, op[1] + op[2])
    fmu.doStep(currentCommunicationPoint=t, communicationStepSize=op[3])
    t += op[3]
    if k in spec["save_at"]:
        out["saved"][str(k)] = fmu.serializeFMUstate(fmu.getFMUstate()).hex()
for blob in spec["blobs"]:
    try:
        fmu.setFMUstate(fmu.deSerializeFMUstate(bytes.fromhex(blob)))
        out["tried"].append(int(fmu.getInteger(active)[0]))
    except FMICallException as exc:
        out["tried"].append("refused %d" % int(exc.status))
json.dump(out, open(sys.argv[2], "w"))
'''


def _fnv1a64(b: bytes) -> int:
    h = 1469598103934665603
    for x in b:
        h = ((h ^ x) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def _reseal(img: bytearray) -> bytes:
    """The glue's trailing FNV-1a 64 recomputed (docs/native-fmu.md): the runtime decides."""
    img[-8:] = struct.pack("<Q", _fnv1a64(bytes(img[:-8])))
    return bytes(img)


def _members(img: bytes, n_inputs: int):
    """(offset of the scheduled runtime image, [(offset, length) of each member's image]):
    glue header 40 bytes, inputs, two i32, then magic | hash | total | active | per member u64 len, image."""
    base = 40 + 8 * n_inputs + 8
    assert img[base:base + 8] == b"FDISCHD1"
    spans, p = [], base + 32
    while p < len(img) - 8:
        (n,) = struct.unpack("<Q", img[p:p + 8])
        spans.append((p + 8, n))
        p += 8 + n
    return base, spans


def _probe(tmp_path, fmu, ops, save_at, blobs):
    spec = tmp_path / f"probe{len(list(tmp_path.glob('probe*.json')))}.json"
    spec.write_text(json.dumps({"fmu": str(fmu), "ops": ops, "save_at": save_at, "blobs": blobs}), encoding="utf-8")
    (tmp_path / "probe.py").write_text(PROBE, encoding="utf-8")
    res = tmp_path / f"{spec.stem}.out.json"
    proc = subprocess.run([sys.executable, str(tmp_path / "probe.py"), str(spec), str(res)], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(res.read_text(encoding="utf-8"))


def test_native_refuses_scheduled_states_no_run_produces(design, tmp_path):
    fmu = build_fmu(design, tmp_path / "s.fmu", target="native")
    ops = [op for op in _ops(120) if op[0] == "step"]
    early, late = 40, 150
    saved = _probe(tmp_path, fmu, ops[:late + 1], [-1, early, late], [])["saved"]
    a, b = bytes.fromhex(saved[str(early)]), bytes.fromhex(saved[str(late)])
    base, spans = _members(b, 3)
    assert len(a) == len(b) and len(spans) == len(design["members"]) and _members(a, 3)[1] == spans

    def with_active(v):
        img = bytearray(b)
        img[base + 24:base + 32] = struct.pack("<q", v)
        return _reseal(img)

    def with_member(k, src):
        img = bytearray(b)
        off, n = spans[k]
        img[off:off + n] = src[off:off + n]
        return _reseal(img)

    late_active = struct.unpack("<q", b[base + 24:base + 32])[0]
    start = bytearray(bytes.fromhex(saved["-1"]))  # no valid sample yet: active -1
    assert struct.unpack("<q", start[base + 24:base + 32])[0] == -1
    start[base + 24:base + 32] = struct.pack("<q", 0)
    blobs = [b, with_active(late_active), with_active(3), with_active(-2), with_member(1, a), with_member(2, a),
             _reseal(start), with_active(0 if late_active != 0 else 1)]
    tried = _probe(tmp_path, fmu, ops[:1], [], [x.hex() for x in blobs])["tried"]
    # b itself and b resealed unchanged are accepted; another valid active index is a state a run can
    # hold (the schedule's choice depends on the path); the rest are refused with fmi2Error (3)
    assert tried[:2] == [late_active + 1] * 2, tried
    assert tried[2:7] == ["refused 3"] * 5, tried
    assert tried[7] == (0 if late_active != 0 else 1) + 1, tried


def test_native_scheduled_state_bit_flips(tmp_path):
    """tests/test_native_state_fuzz.py on a scheduled design (every 61st bit): the checksum refuses
    every raw flip; of the resealed ones, whatever the members' and the schedule's validation
    accept steps in bounded time with outputs in range (two members, two faults: the host's
    Integer range -1..N_FAULTS covers active_member 0..K too)."""
    from test_native_state_fuzz import _judge, fuzz

    mset = ModelSet([_member(1.0 + 0.5 * k, float(k + 1)) for k in range(2)], ["u0"])
    d = json.loads(json.dumps(_design(mset, hysteresis=0.3).design))
    assert len(d["members"]) <= len(d["faults"])
    raw = fuzz(d, tmp_path, 3, stride=61)
    sealed = fuzz(d, tmp_path, 3, stride=61, reseal=True)
    _judge("scheduled", raw, sealed)


def test_both_scheduled_fmus_log_and_refuse_as_plain_ones(tmp_path):
    """The rules of tests/test_fmu_rules.py for a scheduled design, native and pythonfmu through the
    same fmpy contract: the same warnings in the same categories (step size changed, invalid
    sample, overflow under logFdiNumeric) and a bad threshold_scale refused for every member."""
    from test_diagnostic_fmu import _errors, contract

    mset = ModelSet([_member(1.0 + 0.5 * k, float(k + 1)) for k in range(2)], ["u0"])
    d = json.loads(json.dumps(_design(mset, hysteresis=0.3).design))
    fmus = {"native": build_fmu(d, tmp_path / "n.fmu", target="native"), "python": build_fmu(d, tmp_path / "p.fmu")}
    row = {"u0": 1.0, "y0": 1.0, "y1": 1.0}
    actions = [["instantiate", "a", "f"], ["setup", "a"], ["enter", "a"], ["exit", "a"],
               ["step", "a", TS, row], ["step", "a", TS / 2, row], ["step", "a", TS / 2, dict(row, y0=float("nan"))],
               ["step", "a", TS / 2, dict(row, y1=1e300)], ["step", "a", TS / 2, dict(row, u0=2.0)],
               ["scale", "a", -1.0], ["step", "a", TS / 2, row], ["scale", "a", 2.0], ["step", "a", TS / 2, row]]
    logs = {}
    for kind, fmu in fmus.items():
        done, names = contract(tmp_path, {"f": fmu}, actions)
        assert [a["status"] for a in done[4:9]] == [0] * 5, kind
        logs[kind] = [[(s, c, m) for s, c, m in a["log"] if s == 1] for a in done[4:9]]
        overflow, switched = done[7]["values"], done[8]["values"]
        assert overflow[names.index("numeric_reset")] == overflow[names.index("input_invalid")] == 1.0, kind
        assert switched[names.index("active_member")] == 2.0, kind
        bad, after, ok = done[9:12]
        assert "threshold_scale" in _errors(bad), kind
        assert (bad["status"], after["status"]) == ((3, 0) if kind == "native" else (0, 2)), kind
        assert done[12]["status"] == 0 and done[12]["values"][names.index("threshold_1")] == 2 * 0.05, kind
    assert logs["native"] == logs["python"], logs
    changed, invalid, overflow = logs["native"][1:4]
    assert [c for _, c, _ in changed] == ["logStatusWarning"] and "step size changed" in changed[0][2]
    assert [c for _, c, _ in invalid] == ["logFdiInput"] and [c for _, c, _ in overflow] == ["logFdiNumeric"]
