"""Pure-Python reference of the stand-in slave (written apart from ``standin.py``).

``states`` runs the filter, ``outputs`` evaluates the output map; the host tests combine them
according to when each host reads outputs relative to setting inputs (docs/fmu-hosts.md):

* aligned (``FMU2Slave`` loop, C host, container): row k = outputs(x_k, v_k, s_k);
* after step (``fmpy simulate``, libcosim): row k = outputs(x_k, v_{k-1}, s_{k-1}), row 0 aligned.
"""
import math

import numpy as np

T0 = np.array([0.2, 0.3])
OUTPUTS = ("residual_1", "evaluation_1", "threshold_1", "alarm_1", "residual_2", "evaluation_2", "threshold_2",
           "alarm_2", "fault_detected", "isolated_fault", "input_invalid")


def signals(n, h):
    """The test scenario: rows of (time, u1, u2, y1, threshold_scale); y1 has a bias from t = 1."""
    t = np.arange(n) * h
    data = np.zeros(n, dtype=[("time", float), ("u1", float), ("u2", float), ("y1", float), ("threshold_scale", float)])
    data["time"] = t
    data["u1"] = np.sin(2 * t)
    data["u2"] = np.cos(t)
    data["y1"] = np.sin(2 * t) + 0.6 * (t >= 1.0)
    data["threshold_scale"] = np.where(t >= 1.5, 2.0, 1.0)
    return data


def states(v, h, tau=0.5, variant=1.0):
    """x_0 = 0 and x_{k+1} = a_k x_k + (1 - a_k) e_k, a_k = exp(-h_k/tau), for rows v_k = (u1, u2, y1).

    ``h`` is a scalar or one step size per row; a row with a non-finite value holds x."""
    v = np.asarray(v, float)
    hs = np.broadcast_to(np.asarray(h, float), (len(v),))
    x = np.zeros((len(v) + 1, 2))
    for k, (row, hk) in enumerate(zip(v, hs)):
        if not np.all(np.isfinite(row)):
            x[k + 1] = x[k]
            continue
        e = np.array([row[2] - row[0], row[2] - row[1]]) * variant
        a = math.exp(-hk / tau)
        x[k + 1] = a * x[k] + (1.0 - a) * e
    return x


def outputs(x, v, scale, variant=1.0):
    """Output rows for state rows ``x`` (n × 2), input rows ``v`` (n × 3), ``scale`` (n,)."""
    x, v = np.atleast_2d(x), np.atleast_2d(np.asarray(v, float))
    scale = np.broadcast_to(np.asarray(scale, float), (len(v),))
    invalid = ~np.all(np.isfinite(v), axis=1)
    e = np.stack([v[:, 2] - v[:, 0], v[:, 2] - v[:, 1]], axis=1) * variant
    r = np.where(invalid[:, None], 0.0, e - x)
    thr = scale[:, None] * T0
    alarm = np.abs(r) > thr
    n_alarm = alarm.sum(axis=1)
    out = np.zeros(len(v), dtype=[(n, bool if n.startswith(("alarm", "fault", "input")) else
                                      np.int32 if n == "isolated_fault" else float) for n in OUTPUTS])
    for k in (1, 2):
        out[f"residual_{k}"] = r[:, k - 1]
        out[f"evaluation_{k}"] = np.abs(r[:, k - 1])
        out[f"threshold_{k}"] = thr[:, k - 1]
        out[f"alarm_{k}"] = alarm[:, k - 1]
    out["fault_detected"] = n_alarm > 0
    out["isolated_fault"] = np.where(n_alarm == 0, 0, np.where(n_alarm == 1, np.argmax(alarm, axis=1) + 1, -1))
    out["input_invalid"] = invalid
    return out


def aligned(data, h, **kw):
    """Reference rows for hosts that read outputs after setting the inputs of the same row."""
    v = np.column_stack([data["u1"], data["u2"], data["y1"]])
    x = states(v, h, **kw)
    return outputs(x[:-1], v, data["threshold_scale"], variant=kw.get("variant", 1.0))


def after_step(data, h, **kw):
    """Reference rows for hosts that read outputs right after fmi2DoStep (row 0: after init)."""
    v = np.column_stack([data["u1"], data["u2"], data["y1"]])
    x = states(v, h, **kw)
    s = data["threshold_scale"]
    prev = np.r_[0, np.arange(len(v) - 1)]  # inputs still set when row k is read
    return outputs(x[:-1], v[prev], s[prev], variant=kw.get("variant", 1.0))


def assert_matches(result, reference, rows=slice(None), atol=1e-12):
    """Every output field of ``result`` equals ``reference``: Reals to ``atol``, others exactly."""
    for name in OUTPUTS:
        if name not in result.dtype.names:
            continue
        got, want = result[name][rows], reference[name][rows]
        if reference.dtype[name].kind == "f":
            err = np.max(np.abs(got - want)) if len(got) else 0.0
            assert err <= atol, f"{name}: max |error| {err:.3g} > {atol:g}"
        else:
            bad = np.flatnonzero(got.astype(reference.dtype[name]) != want)
            assert bad.size == 0, f"{name}: differs at rows {bad[:10]} (got {got[bad[:5]]}, want {want[bad[:5]]})"


def plant(times, h, bias=0.6):
    """Reference of the plant stand-in: rows (u1, u2, y1) at ``times`` = t_0 + k h from t_0 = 0."""
    times = np.asarray(times, float)
    z = np.zeros(len(times))
    b = math.exp(-h / 0.3)
    for k in range(1, len(times)):
        z[k] = b * z[k - 1] + (1.0 - b) * math.sin(2.0 * times[k - 1])
    return np.column_stack([np.sin(2 * times), np.cos(times), z + bias * (times >= 1.0)])
