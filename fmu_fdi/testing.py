"""Assertions for your own pytest suites: run a co-simulation scenario or a small campaign, then
check what a diagnoser must do — with failure messages that print the evidence.

- :func:`run_scenario`: one co-simulation (a thin call over :class:`~fmu_fdi.cosim.CoSimulation`).
- :func:`assert_detected`: "detected within T (and isolated as F within T)".
- :func:`assert_no_false_alarm`: no alarm in a fault-free record (or before a time).
- :func:`assert_false_alarm_rate`: "no more than rate p per sample at confidence c", from
  fault-free records or a campaign: the one-sided Clopper–Pearson upper bound of the alarmed
  share of samples must not exceed p. With no alarm at all this needs
  ``N ≥ ln(1 − c) / ln(1 − p)`` samples (:func:`samples_needed`; ≈ 3/p at c = 95 %).
- :func:`run_campaign`: a campaign file run into a folder (see :mod:`fmu_fdi.campaign`).

Example::

    from fmu_fdi.testing import assert_detected, assert_no_false_alarm, run_scenario
    from fmu_fdi.cosim import Fault

    def test_level_sensor_bias_is_isolated(plant_fmu, bank_fmu, pumps):
        res = run_scenario({"plant": plant_fmu, "bank": bank_fmu}, inputs=pumps, step=1, stop=600,
                           faults=[Fault.abrupt("plant.f_sensor_h1", 300, 1.0)])
        assert_no_false_alarm(res, until=300)
        assert_detected(res, onset=300, within=20, isolated_as="sensor_h1",
                        fault_names=["sensor_h1", "sensor_h2", "sensor_h3"])

The records are co-simulation results (:class:`~fmu_fdi.cosim.Result`) or anything
:func:`fmu_fdi.metrics.metrics` reads: a ``time`` field and the diagnoser's ``fault_detected``
and ``isolated_fault`` (found by suffix, or named with ``diagnoser=``), optionally its
``evaluation_<i>`` and ``threshold_<i>`` (shown as evidence).
"""
from __future__ import annotations

import math

import numpy as np

from .campaign.aggregate import clopper_pearson
from .metrics import metrics

__all__ = ["run_scenario", "run_campaign", "assert_detected", "assert_no_false_alarm", "assert_false_alarm_rate",
           "samples_needed", "DiagnosisAssertionError"]


class DiagnosisAssertionError(AssertionError):
    """A diagnosis claim failed; the message holds the evidence."""


def run_scenario(fmus, *, step, stop, faults=(), inputs=None, connections="auto", order="jacobi",
                 parameters=None, start=0.0):
    """One co-simulation; returns its :class:`~fmu_fdi.cosim.Result` (Jacobi order by default:
    every (u, y) pair the diagnoser reads is one sample)."""
    from .cosim import CoSimulation

    return CoSimulation(fmus, connections, inputs, step=step, stop=stop, start=start, order=order, faults=faults,
                        parameters=parameters).run()


def run_campaign(campaign, out_dir, *, workers: int = 1, resume: bool = False):
    """Run a campaign file (or :class:`~fmu_fdi.campaign.CampaignSpec`) into ``out_dir``; see
    :func:`fmu_fdi.campaign.run_campaign`."""
    from .campaign import run_campaign as _run

    return _run(campaign, out_dir, workers=workers, resume=resume, progress=False)


def samples_needed(rate: float, confidence: float = 0.95) -> int:
    """Fault-free samples without any alarm that show a false-alarm rate ≤ ``rate`` at
    ``confidence``: the least N with ``(1 − rate)^N ≤ 1 − confidence`` (one-sided Clopper–Pearson
    with k = 0). Examples: 2995 for 1e-3 at 95 %; 46 050 for 1e-4 at 99 %.

    >>> samples_needed(1e-3, 0.95)
    2995
    """
    if not 0 < rate < 1 or not 0 < confidence < 1:
        raise ValueError(f"rate and confidence must lie in (0, 1), got {rate}, {confidence}")
    return math.ceil(math.log(1 - confidence) / math.log1p(-rate) - 1e-9)


# ----------------------------------------------------------------------------- evidence
def _prefix(record, diagnoser) -> str:
    names = list(record.dtype.names) if getattr(getattr(record, "dtype", None), "names", None) else list(record)
    if diagnoser is not None:
        if f"{diagnoser}.fault_detected" in names:
            return f"{diagnoser}."
        raise KeyError(f"record has no diagnoser {diagnoser!r} (no column {diagnoser}.fault_detected)")
    hits = [n[: -len("fault_detected")] for n in names if n == "fault_detected" or n.endswith(".fault_detected")]
    if len(hits) != 1:
        raise ValueError(f"record has {len(hits)} diagnosers ({[h.rstrip('.') for h in hits]}): name one with "
                         f"diagnoser=")
    return hits[0]


def _ratios(record, prefix, mask) -> str:
    names = record.dtype.names if getattr(getattr(record, "dtype", None), "names", None) else list(record)
    out = []
    i = 1
    while f"{prefix}evaluation_{i}" in names and f"{prefix}threshold_{i}" in names:
        J = np.asarray(record[f"{prefix}evaluation_{i}"], float)[mask]
        th = np.asarray(record[f"{prefix}threshold_{i}"], float)[mask]
        if J.size:
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.where(th > 0, J / th, np.inf)
            k = int(np.argmax(r))
            out.append(f"group {i}: max J/J_th = {r[k]:.3g} at sample {k}")
        i += 1
    return "; ".join(out) if out else "no evaluation/threshold outputs recorded"


def _episodes(t, flag, limit=5) -> str:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flag.astype(int), [0]])))
    pairs = list(zip(edges[::2], edges[1::2]))
    text = ", ".join(f"[{t[a]:g}, {t[b - 1]:g}]" for a, b in pairs[:limit])
    return text + (f" and {len(pairs) - limit} more" if len(pairs) > limit else "")


# ----------------------------------------------------------------------------- assertions
def assert_detected(record, *, onset: float, within: float, isolated_as=None, fault_names=None, diagnoser=None,
                    end: float | None = None):
    """Assert that the diagnoser raised its alarm within ``within`` seconds of ``onset`` and,
    with ``isolated_as``, named that fault within the same time.

    Parameters
    ----------
    record : Result or structured array
        The run (time, ``<diagnoser>.fault_detected``, ``<diagnoser>.isolated_fault``).
    onset : float
        When the fault was switched on.
    within : float
        The largest acceptable detection (and isolation) delay, seconds.
    isolated_as : str or int, optional
        The fault the isolation must name: its name (with ``fault_names``, the diagnoser's fault
        list in order) or its 1-based index.
    fault_names : list of str, optional
    diagnoser : str, optional
        Instance name; default the record's only diagnoser.
    end : float, optional
        When the fault was switched off (default: never).

    Raises
    ------
    DiagnosisAssertionError
        With the first alarm, the isolation values seen after the onset and how long each was
        held, the alarms before the onset and the largest evaluation/threshold ratios.
    """
    prefix = _prefix(record, diagnoser)
    fault = None
    if isolated_as is not None:
        if isinstance(isolated_as, str):
            if not fault_names or isolated_as not in fault_names:
                raise ValueError(f"isolated_as={isolated_as!r}: give fault_names containing it (got {fault_names})")
            fault = list(fault_names).index(isolated_as) + 1
        else:
            fault = int(isolated_as)
    m = metrics(record, t_on=onset, t_off=end, fault=fault, alarm=prefix + "fault_detected",
                isolation=prefix + "isolated_fault")
    ok_detect = m.t_dt <= within
    ok_iso = fault is None or m.t_it <= within
    if ok_detect and ok_iso:
        return m
    t = np.asarray(record["time"], float)
    alarm = np.asarray(record[prefix + "fault_detected"]) != 0
    iso = np.asarray(record[prefix + "isolated_fault"]).astype(int)
    after = t >= onset - 1e-9 * max(1.0, abs(onset))
    values, counts = np.unique(iso[after], return_counts=True)
    name = (lambda j: fault_names[j - 1] if fault_names and 0 < j <= len(fault_names) else
            {0: "none", -1: "unknown"}.get(j, f"fault {j}"))
    seen = ", ".join(f"{name(int(v))} for {int(c)} samples" for v, c in zip(values, counts))
    what = (f"not detected within {within:g} s of the onset at {onset:g} s" if not ok_detect else
            f"not isolated as {isolated_as!r} within {within:g} s of the onset at {onset:g} s")
    lines = [f"{prefix.rstrip('.') or 'diagnoser'}: {what}",
             f"  detection delay t_dt = {m.t_dt:g} s" + ("" if math.isfinite(m.t_dt) else " (no alarm after the onset)"),
             f"  isolation after the onset: {seen or 'no samples'}"
             + (f"; t_it = {m.t_it:g} s" if fault is not None else ""),
             f"  alarms before the onset: {_episodes(t, alarm & ~after) or 'none'}",
             f"  after the onset: {_ratios(record, prefix, after)}"]
    raise DiagnosisAssertionError("\n".join(lines))


def assert_no_false_alarm(record, *, until: float | None = None, since: float | None = None, diagnoser=None):
    """Assert that the diagnoser raised no alarm at the samples ``since ≤ t ≤ until`` (default
    the whole record: a fault-free run). The failure message lists the alarm episodes and the
    largest evaluation/threshold ratios."""
    prefix = _prefix(record, diagnoser)
    t = np.asarray(record["time"], float)
    mask = np.ones(t.shape, bool)
    if until is not None:
        mask &= t <= until + 1e-9 * max(1.0, abs(until))
    if since is not None:
        mask &= t >= since - 1e-9 * max(1.0, abs(since))
    alarm = (np.asarray(record[prefix + "fault_detected"]) != 0) & mask
    if not alarm.any():
        return
    span = f"[{t[mask][0]:g}, {t[mask][-1]:g}]" if mask.any() else "(empty)"
    raise DiagnosisAssertionError(
        f"{prefix.rstrip('.') or 'diagnoser'}: {int(alarm.sum())} alarmed sample(s) of {int(mask.sum())} in the "
        f"fault-free span {span} s\n  alarm episodes: {_episodes(t, alarm)}\n  {_ratios(record, prefix, mask)}")


def assert_false_alarm_rate(evidence, *, rate: float, confidence: float = 0.95, diagnoser=None,
                            until: float | None = None):
    """Assert a false-alarm rate per sample of at most ``rate`` at ``confidence``: the one-sided
    Clopper–Pearson upper bound of ``k / N`` (k alarmed among N fault-free samples) must be
    ≤ ``rate``.

    Parameters
    ----------
    evidence : list of records, CampaignResults, or (k, N)
        Fault-free records (each scored up to ``until``, default whole), a campaign's results
        (its fault-free samples, :mod:`fmu_fdi.campaign.execute`; ``diagnoser`` required if it has
        several), or the counts.
    rate, confidence : float

    Returns
    -------
    (k, N, upper bound)

    Notes
    -----
    The bound treats the samples as independent trials. An evaluation over a window makes
    neighbouring samples dependent, so a campaign of many independent runs is better evidence
    than one long run with the same N.
    """
    k, n, source = _counts(evidence, diagnoser, until)
    if n == 0:
        raise DiagnosisAssertionError("no fault-free samples to judge a false-alarm rate by")
    upper = clopper_pearson(k, n, confidence, "upper")[1]
    if upper <= rate:
        return k, n, upper
    need = samples_needed(rate, confidence)
    hint = (f"with no alarm at all, {need} samples would show it ({n} given)" if k == 0 else
            f"{k} alarmed samples already put the estimate k/N = {k / n:.3g} "
            + ("above" if k / n > rate else "too close to") + " the target")
    raise DiagnosisAssertionError(
        f"false-alarm rate not shown to be <= {rate:g} per sample at {confidence:.0%} confidence: {k} alarmed of "
        f"{n} fault-free samples{source}, upper bound {upper:.3g}\n  {hint}")


def _counts(evidence, diagnoser, until):
    if isinstance(evidence, tuple) and len(evidence) == 2:
        return int(evidence[0]), int(evidence[1]), ""
    records = getattr(evidence, "records", None)
    if records is not None:  # CampaignResults
        ok = [r for r in records if r["status"] == "ok"]
        names = sorted({d for r in ok for d in r["diagnosers"]})
        if diagnoser is None:
            if len(names) != 1:
                raise ValueError(f"campaign has diagnosers {names}: name one with diagnoser=")
            diagnoser = names[0]
        k = sum(r["diagnosers"][diagnoser]["alarm_samples"] for r in ok if diagnoser in r["diagnosers"])
        n = sum(r["diagnosers"][diagnoser]["samples"] for r in ok if diagnoser in r["diagnosers"])
        return k, n, f" over {len(ok)} campaign runs"
    k = n = 0
    for rec in evidence:
        prefix = _prefix(rec, diagnoser)
        t = np.asarray(rec["time"], float)
        mask = t > t[0]  # row 0 is the state after initialisation, not a diagnosis
        if until is not None:
            mask &= t <= until + 1e-9 * max(1.0, abs(until))
        k += int(((np.asarray(rec[prefix + "fault_detected"]) != 0) & mask).sum())
        n += int(mask.sum())
    return k, n, f" in {len(evidence)} record(s)"
