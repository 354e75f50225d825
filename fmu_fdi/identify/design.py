"""Automatic experiment design: sample time, duration, signal and amplitude from a pre-test.

Every choice the user left open (an :class:`~fmu_fdi.identify.experiment.Excitation` field at
None, no ``ts``) is made from what a short pre-test on the plant FMU shows:

1. **Noise level at the operating point.** The pre-test first holds every input at its
   operating value for the settle phase (``MIN_SETTLE`` samples); the noise level σ_j of each
   output is read over the second half of it by
   :func:`~fmu_fdi.identify.validation.settle_noise_std` (the plain std — white sensor noise and
   coloured process noise alike — unless a recursion predicts the record: then it is a settling
   transient, and the noise is that recursion's error).
   Noise coloured by a slow or lightly damped mode outlasts that window, so σ_j is raised to
   the std of the pre-test model's output error (after its first fifth) when that is larger.
2. **Time scales.** Then a multisine (all inputs at once, disjoint lines log-spaced from the
   lowest resolvable frequency to half the Nyquist frequency, :func:`excitation_signals`)
   runs for ``PRETEST_SAMPLES`` steps; a PO-MOESP model of it gives the poles z_i, and with
   λ_i = log(z_i)/ts the fastest time scale τ_min = 1/max|λ_i| (at least ts) and the slowest
   τ_max = 1/min|Re λ_i| (at most 10× the pre-test's length).
   If no output's response std rises above its σ, the pre-test amplitude is raised by the
   factor that would give 2 σ (2 to 10-fold, within the limits below) and the pre-test
   repeated, three times at most.
   *Slow modes the pre-test does not see settle* (:func:`_slow_stages`): when τ_max exceeds a
   third of the pre-test and its model leaves a response unexplained (misfit above
   ``SLOW_MISFIT`` times the settle noise), the pre-test is repeated with a 10 times coarser
   step (10 times longer), at most twice, each stage's slowest time scale replacing τ_max
   (wind turbine drive train: 11.9 s from the first, 158 s from the second, 139 s from the
   third; the rotor mode is 138 s).
3. **Choices** (Ljung 1999, ch. 13; Pintelon & Schoukens 2012, ch. 5):

   - *signal*: a PRBS — crest factor 1, the most power for a given peak, which is what the
     declared limits and the plant's linear range bound;
   - *sample time* ts (when neither it nor samples nor period, counted in steps, is given):
     the FMU's default step, or its largest multiple below τ_min/10 — ten
     samples per fastest time scale (the pre-test's τ_min may be off by 2); finer sampling leaves the s = max_order + 1 block rows of
     the subspace method a window far shorter than the dynamics, and the estimates scatter
     (DTS200: ts = 1 s against τ_min ≈ 21 s gave a 17 % frequency-response error, ts = 4 s 7 %);
   - *a stiff plant* (τ_max/τ_min > ``STIFF_RATIO``; the drive train: 0.036 s and 139 s): when
     the budget binds, ts may grow to τ_min (not τ_min/3: the fastest pole stays resolved,
     z = e^{−1}, and the model is refined by output error on the exact zero-order-hold
     sampling, :mod:`fmu_fdi.identify.output_error`, which no sample time biases); the PRBS
     gets a slow companion (half the amplitude each, clock τ_max/``SLOW_CLOCK_TAUS``: flat to
     0.44·4/τ_max Hz, a decade above the slow corner 1/(2π τ_max)) — a single PRBS with the
     fast clock spreads its power to 0.44/(P ts) Hz and leaves the slow mode's outputs (the
     rotor speed) below their noise. Its response is predicted by the slow pre-test's model
     and the probe is skipped (a short probe cannot see the slow component; the estimation
     run's own signal/noise check stands);
   - *clock period* P = round(τ_min / ts) ≥ 1: the PRBS spectrum is flat to within 3 dB up to
     0.44/(P ts) Hz, which covers 1/(2π τ_min); at most a fiftieth of a given record (the
     input must stay persistently exciting of order 2s);
   - *duration* T = 6 τ_max (frequency resolution 1/T below the slowest mode's corner
     1/(2π τ_max)), at least ``MIN_SAMPLES``; the budget is counted in samples, never in wall
     time (the experiment, hence the model, is a function of the FMU and the options only, not
     of the machine's speed or load): when T/ts exceeds ``MAX_SAMPLES``, ts becomes a multiple
     of the FMU's step, at most τ_min/3, and the record is cut at ``MAX_SAMPLES`` (a note says
     how many slowest time scales it covers); a given ``samples`` or ``ts`` caps it;
   - *settle* (the phase at the operating point before each run): until the outputs are steady.
     The pre-test's settle record holds the start's transient d_j (when its peak-to-peak exceeds
     the ±3 σ_j of noise: that plus 6 σ_j, an upper bound; else zero); the slowest
     mode decays as e^{−t/τ_max}, so the transient that remains after T_s is
     a_j = d_j / (1 − e^{−T_s/τ_max}), and it is below the tolerance tol_j after
     τ_max·ln(a_j / tol_j). tol_j = max(σ_j / 10, response_j / 1000): a tenth of the noise, or
     on a noise-free plant a thousandth of the excitation's response (the operating point y0 is
     then exact to the identification's own accuracy). At least ``MIN_SETTLE`` samples, at most
     ``SETTLE_TAUS`` τ_max (e^{−10} = 4.5e-5 of the transient) and ``MAX_SETTLE`` samples. When
     the pre-test itself ran on a transient larger than tol_j, it is repeated once after that
     settle (its time scales and noise level were read on a moving plant);
   - *amplitude*: the rough model's response to the chosen PRBS at the seed amplitude
     predicts each output's response std r_j; the amplitude is scaled by c ≥ 1 so that
     min_j r_j c / σ_j reaches ``SNR_TARGET``; a probe run of the chosen signal
     (``PROBE_SAMPLES``) then measures r_j at that amplitude and c is set again from it
     (up or down, not below the seed); in all, at most ``MAX_GROWTH`` times the seed
     amplitude (the plant's linear range is unknown; 100 times when the seed is the bare FMI
     default nominal, whose scale means nothing) and within 90 % of the declared min/max. When the cap leaves the
     signal-to-noise ratio short, the record is lengthened by (target/achieved)² (the
     variance of the estimates falls as 1/(N·SNR²), Ljung 1999 eq. 9.62) within the budget.
   - *a plant in its own loop* (model inputs that are FMU outputs, identified from its
     references by :mod:`fmu_fdi.identify.closed_loop`): each reference is the instrument of
     its own model input, so each is raised until it alone reaches ``SNR_TARGET`` on its
     best-seen output (DR300: a load torque the PI loop integrates met the common target alone
     and left the speed reference at ±0.07, whose model then missed the plant's slow pole);
   - *seed amplitude* per input: 5 % of its operating value; at a zero operating point
     5 % of its declared range (max − min), else 5 % of its nominal (FMI default 1).

References
----------
L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall 1999.
R. Pintelon and J. Schoukens, *System Identification: A Frequency Domain Approach*, 2nd ed., Wiley 2012.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .errors import IdentificationError
from .experiment import Excitation, _limit, excitation_signals, run_experiment
from .validation import settle_noise_std

PRETEST_SAMPLES = 1000
#: samples at the operating point before the pre-test, and the fewest before a run
MIN_SETTLE = 200
#: the settle phase lasts at most this many slowest time scales ...
SETTLE_TAUS = 10.0
#: ... and at most this many samples
MAX_SETTLE = 20000
#: length of the probe run of the chosen signal that measures the response at the chosen amplitude
PROBE_SAMPLES = 400
SNR_TARGET = 10.0
MAX_GROWTH = 4.0
MIN_SAMPLES = 1000
#: samples per fastest time scale: ts = the FMU step's largest multiple below τ_min / TS_PER_TAU
TS_PER_TAU = 10.0
#: the most samples a run's record holds (the budget: samples, not wall time)
MAX_SAMPLES = 20000
#: slow pre-tests: at most this many, each with a step this many times coarser (module docstring, 2)
SLOW_STAGES = 2
#: ... when the first pre-test model's misfit exceeds the settle phase's noise std this many times
SLOW_MISFIT = 5.0
SLOW_STAGE_FACTOR = 10
#: a plant is stiff when its slowest time scale exceeds its fastest this many times (module docstring, 3)
STIFF_RATIO = 1000.0
#: a stiff plant's slow PRBS clock: the slowest time scale over this
SLOW_CLOCK_TAUS = 4.0


@dataclass
class ExperimentPlan:
    """The experiment chosen for a plant FMU and what the choice was based on."""

    ts: float
    excitation: Excitation
    noise_std: dict
    response_std: dict
    tau: tuple
    chosen: list
    steps_per_second: float
    notes: list = field(default_factory=list)
    #: largest amplitude of each input whose amplitude was chosen here
    limits: dict = field(default_factory=dict)
    #: the settle phase's noise std per output (``noise_std`` may exceed it: the pre-test model's misfit
    #: bounds coloured noise from above)
    noise_settle: dict = field(default_factory=dict)

    def adapted(self, record) -> Excitation | None:
        """A stronger excitation when the run ``record`` fell short of the signal/noise target.

        The achieved response std per output is ``sqrt(max(var(y − y0) − σ², 0))``; when its
        smallest ratio to σ (noisy outputs) is below ``SNR_TARGET``/2, the chosen amplitudes grow
        by the missing factor within their limits (the pre-test's model predicts the response
        only roughly). None when nothing is to change."""
        if not self.limits:
            return None
        sigma = np.array([self.noise_std[n] for n in record.y_names])
        noisy = sigma > 0
        if not np.any(noisy):
            return None
        dy = record.y - record.y0
        r = np.sqrt(np.maximum(dy.var(axis=0) - sigma ** 2, 0.0))
        snr = float(np.min(r[noisy] / sigma[noisy]))
        if snr >= SNR_TARGET / 2:
            return None
        c = SNR_TARGET / max(snr, 1e-3)
        amp = dict(self.excitation.amplitude)
        grown = {k: (min(a * c, self.limits[k]) if k in self.limits else a) for k, a in amp.items()}
        if all(grown[k] <= amp[k] * 1.01 for k in grown):
            return None
        self.notes.append(f"the estimation run reached signal/noise {snr:.2g} (< {SNR_TARGET / 2:g}): amplitudes "
                          f"raised to {', '.join(f'{k} ±{v:.4g}' for k, v in grown.items())} and the run repeated")
        self.excitation = replace(self.excitation, amplitude=grown)
        return self.excitation

    def describe(self) -> str:
        """Multi-line text: the experiment and why (printed by ``fmu-fdi model``)."""
        e = self.excitation
        amps = ", ".join(f"{k} ±{v:.4g}" for k, v in e.amplitude.items())
        auto = f" (chosen: {', '.join(self.chosen)})" if self.chosen else " (all given)"
        lines = [f"experiment{auto}: {e.signal}"
                 + (f" clock {e.period} steps" if e.signal == "prbs" else "")
                 + (f" + slow PRBS clock {e.slow_period} steps" if e.slow_period is not None else "")
                 + f", {amps}; ts = {self.ts:g} s, {e.samples} samples ({e.samples * self.ts:g} s) per run, "
                   f"settle {e.settle:g} s",
                 "  pre-test: time scales {:.3g} .. {:.3g} s; noise std at the operating point {}".format(
                     self.tau[0], self.tau[1], ", ".join(
                         f"{k} {v:.3g}" + (f" (misfit bound; settle {self.noise_settle[k]:.3g})"
                                           if self.noise_settle.get(k, v) < v / 1.5 else "")
                         for k, v in self.noise_std.items())),
                 "  predicted response std (signal/noise) {}".format(", ".join(
                     f"{k} {v:.3g} ({v / self.noise_std[k]:.3g})" if self.noise_std[k] > 0 else f"{k} {v:.3g} (no noise)"
                     for k, v in self.response_std.items()))]
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def seed_amplitude(var, v0: float) -> float:
    """5 % of the operating value; at 0, of the declared range; else of the nominal (default 1)."""
    if v0 != 0.0:
        return 0.05 * abs(v0)
    lo, hi = _limit(var.min), _limit(var.max)
    if lo is not None and hi is not None and hi > lo:
        return 0.05 * (hi - lo)
    nominal = _limit(getattr(var, "nominal", None))
    return 0.05 * abs(nominal) if nominal else 0.05


def headroom(var, v0: float) -> float:
    """Largest symmetric deviation from v0 inside the declared [min, max] (inf if undeclared)."""
    lo, hi = _limit(var.min), _limit(var.max)
    room = np.inf
    if lo is not None:
        room = min(room, v0 - lo)
    if hi is not None:
        room = min(room, hi - v0)
    return room


def plan_experiment(path, sig, y_names, *, excite, at, parameters, ts, step, excitation: Excitation,
                    max_order: int = 10) -> ExperimentPlan:
    """Choose what ``excitation`` and ``ts`` leave open from a pre-test (module docstring).

    Parameters
    ----------
    path : FMU; sig, y_names : recorded model inputs (u then d) and outputs;
    excite : FMU inputs to excite (None: the model inputs that are FMU inputs);
    at, parameters : operating point and parameters;
    ts : the user's sample time or None; step : the FMU's default step;
    excitation : the user's choices (None fields are chosen here).
    """
    from .linearise import read_description

    from ..cosim.elements import variables_by_name

    md = read_description(path)
    by_name = variables_by_name(md)  # FMI 3 array elements 'u[1]' too
    excite = list(excite) if excite is not None else [n for n in sig if by_name.get(n) is not None
                                                      and by_name[n].causality == "input"]
    if not excite:  # run_experiment names the problem
        excite = None
    at = dict(at or {})
    user = excitation
    ts0 = float(ts if ts is not None else step)
    given_amp = user.amplitude
    seed_amp, limit = _seed_amplitudes(excite, by_name, at, given_amp)
    settle = user.settle if user.settle is not None else MIN_SETTLE * ts0
    settle_given = user.settle is not None
    kw = dict(excite=excite, at=at, parameters=parameters, ts0=ts0, seed=user.seed, limit=limit,
              given_amp=given_amp, max_order=max_order)
    pre, pre_exc, sigma, dy, seed_amp, notes = _pretest(path, sig, y_names, settle=settle, seed_amp=seed_amp, **kw)
    rough, z = _rough_model(pre, pre_exc, dy, ts0, max_order, notes)
    sigma_settle, sigma = sigma, _with_misfit(sigma, rough, pre, pre_exc, dy)
    if not settle_given:  # the pre-test ran on the start's transient: once more, after it has died out
        longer = _steady_settle(pre, sigma, dy, _time_scales(z, ts0)[1], ts0, ts0)
        if longer > settle * (1 + 1e-9):
            notes.append(f"the pre-test started on a transient: repeated after settling {longer:g} s")
            settle = longer
            pre, pre_exc, sigma, dy, seed_amp, more = _pretest(path, sig, y_names, settle=settle,
                                                               seed_amp=seed_amp, **kw)
            notes += more
            rough, z = _rough_model(pre, pre_exc, dy, ts0, max_order, notes)
            sigma_settle, sigma = sigma, _with_misfit(sigma, rough, pre, pre_exc, dy)
    tau_max_slow, sigma = _slow_stages(path, sig, y_names, _time_scales(z, ts0)[1], sigma_settle, sigma,
                                       settle=settle, seed_amp=seed_amp, notes=notes, **kw)
    # round-off is no noise: a std below 1e-9 of the output's level and response counts as zero
    level = np.maximum(np.abs(pre.y0), dy.std(axis=0))
    sigma = np.where(sigma > 1e-9 * level, sigma, 0.0)
    rate = pre.steps / max(pre.seconds, 1e-6)  # reported only: the plan never depends on the machine's speed
    names = list(pre.excited)
    tau_min, tau_max = _time_scales(z, ts0)
    tau_max = max(tau_max_slow[0], tau_min)
    slow_model = tau_max_slow[1]
    ts_new, signal, period, samples, slow_period, chosen = _timing(user, ts, ts0, tau_min, tau_max, notes)
    if not settle_given:  # until the outputs are steady, on the chosen ts's grid
        settle = _steady_settle(pre, sigma, dy, tau_max, ts0, ts_new)
        chosen.insert(int("ts" in chosen), "settle")
    cap = MAX_SAMPLES
    # amplitude: predicted response of the rough model to the chosen signal at the seed amplitude
    exc = Excitation(signal, dict(seed_amp), samples, settle, user.band, period, user.seed, slow_period)
    r = _predicted_response(rough, exc, names, seed_amp, pre, ts_new, ts0, slow_model)
    amp = dict(seed_amp)
    auto_limits = {}
    noisy = sigma > 0
    if given_amp is None or isinstance(given_amp, dict) and len(given_amp) < len(amp):
        free = [k for k in amp if not (isinstance(given_amp, dict) and k in given_amp)]
        chosen.append("amplitude")
        auto_limits = {k: limit[k] for k in free}
        for trial in range(2):  # the rough model's guess, then the measured response of the signal itself
            snr = np.min(r[noisy] / sigma[noisy]) if np.any(noisy) and np.all(r[noisy] > 0) else np.inf
            c = 1.0 if not np.isfinite(snr) else max(SNR_TARGET / max(snr, 1e-12), 1.0 if trial == 0 else 0.0)
            new = {k: (min(max(amp[k] * c, seed_amp[k]), limit[k]) if k in free else amp[k]) for k in amp}
            r = r * min(new[k] / amp[k] for k in amp)
            amp = new
            if trial == 1 or not np.any(noisy) or slow_period is not None:
                break  # (a short probe cannot see a slow component: the estimation run is checked instead)
            # a short run of the chosen signal: what the outputs really do at this amplitude
            probe = Excitation(signal, dict(amp), int(min(samples, max(PROBE_SAMPLES, 20 * period))), settle,
                               user.band, period, user.seed + 2000)
            rec = run_experiment(path, sig, y_names, excite=excite, at=at, parameters=parameters, step=ts_new,
                                 excitation=probe, check_settle=False)
            r = np.sqrt(np.maximum((rec.y - rec.y0).var(axis=0) - sigma ** 2, 0.0))
        if set(names) != set(sig) and rough is not None and np.any(noisy):
            amp = _each_reference_seen(rough, exc, names, amp, free, limit, sigma, ts_new, ts0, notes)
        snr_now = np.min(r[noisy] / sigma[noisy]) if np.any(noisy) and np.all(r[noisy] > 0) else np.inf
        if user.samples is None and np.isfinite(snr_now) and snr_now < SNR_TARGET:
            longer = int(min(cap, np.ceil(samples * (SNR_TARGET / snr_now) ** 2)))
            if longer > samples:
                notes.append(f"signal/noise {snr_now:.2g} < {SNR_TARGET:g} at the largest amplitude allowed: "
                             f"{longer} samples instead of {samples}")
                samples = longer
    exc = replace(exc, amplitude=amp, samples=samples)
    exc = replace(exc, settle=settle)
    return ExperimentPlan(ts_new, exc, dict(zip(y_names, sigma.tolist())), dict(zip(y_names, r.tolist())),
                          (tau_min, tau_max), chosen, rate, notes, auto_limits,
                          dict(zip(y_names, np.asarray(sigma_settle, float).tolist())))


def _timing(user, ts, ts0, tau_min, tau_max, notes):
    """Stage of :func:`plan_experiment`: the sample time, signal, PRBS clock (and a stiff plant's slow
    clock) and record length that ``user`` leaves open (module docstring, 3). Returns ``(ts, signal,
    period, samples, slow_period, chosen)``."""
    stiff = tau_max / tau_min > STIFF_RATIO
    chosen = []
    # sample time and duration within the budget of MAX_SAMPLES per record
    want = 6.0 * tau_max
    ts_new = ts0
    if ts is None and user.samples is None and user.period is None:  # (given in steps: at the FMU's step)
        k = max(1, int(np.floor(tau_min / (TS_PER_TAU * ts0))))
        if want / (k * ts0) > MAX_SAMPLES:
            k_budget = int(np.ceil(want / (ts0 * MAX_SAMPLES)))
            k = max(k, min(k_budget, int(np.floor(tau_min / ((1 if stiff else 3) * ts0)))))
        ts_new = k * ts0
        if k > 1:
            chosen.append("ts")
    signal = user.signal or "prbs"
    if user.signal is None:
        chosen.append("signal")
    period = user.period
    if period is None:
        period = max(1, int(round(tau_min / ts_new)))
        chosen.append("period")
    samples = user.samples
    if samples is not None and user.period is None:  # at least 50 clock periods in a given record
        period = max(1, min(period, samples // 50))
    if samples is None:
        samples = int(min(MAX_SAMPLES, max(MIN_SAMPLES, np.ceil(want / ts_new), 40 * period)))
        chosen.append("samples")
        if samples * ts_new < want:
            notes.append(f"the record covers {samples * ts_new / tau_max:.2g} slowest time scales (6 wanted) "
                         f"within the budget of {MAX_SAMPLES} samples")
    slow_period = None
    if stiff and signal == "prbs" and user.period is None:
        slow_period = max(period, int(round(tau_max / (SLOW_CLOCK_TAUS * ts_new))))
        notes.append(f"a stiff plant (time scales {tau_min:.3g} .. {tau_max:.3g} s, ratio > {STIFF_RATIO:g}): a slow "
                     f"PRBS (clock {slow_period} steps) added to the fast one, half the amplitude each")
    return ts_new, signal, period, samples, slow_period, chosen


def _seed_amplitudes(excite, by_name, at, given_amp):
    """Stage of :func:`plan_experiment`: each excited input's seed amplitude (given, or from its
    range or nominal, inside its headroom) and the largest amplitude the plan may grow it to."""
    v0, seed_amp, room, limit = {}, {}, {}, {}
    for nm in excite or []:
        var = by_name.get(nm)
        if var is None:
            continue
        start = _limit(var.start)
        v0[nm] = float(at[nm]) if nm in at else (start or 0.0)
        a = given_amp.get(nm) if isinstance(given_amp, dict) else given_amp
        seed_amp[nm] = float(a) if a is not None else seed_amplitude(var, v0[nm])
        room[nm] = headroom(var, v0[nm])
        if a is None and seed_amp[nm] > room[nm]:
            seed_amp[nm] = 0.5 * room[nm]
        # the amplitude may grow MAX_GROWTH-fold from a seed that has a scale (operating value, range or
        # declared nominal); from the bare FMI default nominal 1 the scale is unknown: 100-fold
        scaled = v0[nm] != 0.0 or _limit(getattr(var, "nominal", None)) or headroom(var, 0.0) < np.inf
        limit[nm] = min(seed_amp[nm] * (MAX_GROWTH if scaled else 100.0), 0.9 * room[nm])
    return seed_amp, limit


def _pretest(path, sig, y_names, *, excite, at, parameters, ts0, settle, seed, seed_amp, limit, given_amp,
             max_order):
    """Stage of :func:`plan_experiment`: the short multisine pre-test, its amplitude raised up to
    three times until an output responds above its noise. Returns ``(record, excitation, noise
    std, output deviations, seed amplitudes, notes)``."""
    notes = []
    sigma = None
    for attempt in range(4):
        pre_exc = Excitation("multisine", dict(seed_amp), PRETEST_SAMPLES, settle, 0.5, 1, seed + 1000)
        pre = run_experiment(path, sig, y_names, excite=excite, at=at, parameters=parameters, step=ts0,
                             excitation=pre_exc, check_settle=False)
        half = pre.settle_y[len(pre.settle_y) // 2:]
        # a settling transient is no noise (it would loosen the settle check and the signal/noise target)
        sigma = settle_noise_std(half, max_order) if len(half) > 1 else np.zeros(len(y_names))
        dy = pre.y - pre.y0
        resp = np.sqrt(np.maximum(dy.var(axis=0) - sigma ** 2, 0.0))
        if np.any(resp > sigma) or given_amp is not None:
            break
        factor = float(np.clip(2.0 / max(float(np.max(resp / np.maximum(sigma, 1e-300))), 1e-3), 2.0, 10.0))
        grown = {k: min(factor * a, limit[k]) for k, a in seed_amp.items()}
        if all(grown[k] <= seed_amp[k] for k in grown):
            break
        notes.append(f"pre-test {attempt + 1}: no output above its noise; amplitude raised to "
                     + ", ".join(f"{k} ±{v:.3g}" for k, v in grown.items()))
        seed_amp = grown
    if not np.any(resp > sigma):
        raise IdentificationError(
            f"{path}: no output responds above its noise in the pre-test (response std "
            f"{', '.join(f'{n} {r:.3g}' for n, r in zip(y_names, resp))}, noise std "
            f"{', '.join(f'{n} {s:.3g}' for n, s in zip(y_names, sigma))}, amplitudes {seed_amp}): give larger "
            f"amplitudes (--amplitude NAME=A) or check that the inputs act on the outputs")
    return pre, pre_exc, sigma, dy, seed_amp, notes


def _rough_model(pre, pre_exc, dy, ts0, max_order, notes):
    """Stage of :func:`plan_experiment`: the pre-test's PO-MOESP model from the applied excitation
    (references, for a plant in its own loop) to the outputs, and its discrete poles (None and
    none when it fails: the time scales are then the pre-test's length)."""
    from .subspace import moesp

    names = list(pre.excited)
    dev = excitation_signals(pre_exc, names, [pre.excited[k] for k in names])
    try:
        rough = moesp(dev, dy, ts0, None, max_order=max_order, feedthrough=False)
        return rough, np.linalg.eigvals(rough.A)
    except IdentificationError as exc:
        notes.append(f"pre-test model failed ({exc}); time scales assumed from the pre-test's length")
        return None, np.zeros(0)


def _with_misfit(sigma, rough, pre, pre_exc, dy):
    """Stage of :func:`plan_experiment`: coloured noise outlasts a short settle window, and is smooth
    enough there to pass for a transient: the pre-test model's misfit (after its first fifth)
    bounds it from above, so each noisy output's σ is raised to it."""
    if rough is None:
        return sigma
    names = list(pre.excited)
    res = dy - rough.simulate(excitation_signals(pre_exc, names, [pre.excited[k] for k in names]))
    res = res[len(res) // 5:]
    return np.where(sigma > 0, np.maximum(sigma, res.std(axis=0)), 0.0)


def _steady_settle(pre, sigma, dy, tau_max, ts0, ts) -> float:
    """Stage of :func:`plan_experiment`: the settle time after which the start's transient is below
    a tenth of the noise (a thousandth of the response on a noise-free output), on the grid of
    ``ts`` (module docstring, *settle*)."""
    z = pre.settle_y
    n_min = MIN_SETTLE * ts
    if z is None or len(z) < 2:
        return n_min
    T_s = len(z) * ts0
    noise = np.nan_to_num(np.asarray(sigma, float))
    # the transient seen over the pre-test's settle: a peak-to-peak beyond the ±3 σ of noise, bounded from
    # above (noise within ±3 σ hides at most 6 σ of it; an overestimate only settles longer)
    ptp = np.ptp(z, axis=0)
    d = np.where(ptp > 6.0 * noise, ptp + 6.0 * noise, 0.0)
    a = d / max(-np.expm1(-T_s / tau_max), 1e-12)
    tol = np.maximum(noise / 10.0, dy.std(axis=0) / 1000.0)
    tiny = np.finfo(float).tiny
    need = np.where(a > tol, tau_max * np.log(np.maximum(a, tiny) / np.maximum(tol, tiny)), 0.0)
    T = min(float(np.max(need)) if need.size else 0.0, SETTLE_TAUS * tau_max, MAX_SETTLE * ts)
    return max(n_min, float(np.ceil(T / ts)) * ts)


def _time_scales(z, ts0):
    """Stage of :func:`plan_experiment`: the fastest and slowest time scales ``(tau_min, tau_max)``
    of the pre-test model's discrete poles ``z`` (the pre-test's length when there are none)."""
    T_pre = PRETEST_SAMPLES * ts0
    lam = np.log(np.where(np.abs(z) > 1e-12, z, 1e-12).astype(complex)) / ts0
    tau_min = max(1.0 / np.max(np.abs(lam)), ts0) if lam.size else ts0
    slow = np.abs(lam.real)
    tau_max = min(1.0 / max(float(slow.min()), 1e-300), 10 * T_pre) if lam.size else T_pre
    tau_max = max(tau_max, tau_min)
    return tau_min, tau_max


def _each_reference_seen(rough, exc, names, amp, free, limit, sigma, ts, ts0, notes) -> dict:
    """Stage of :func:`plan_experiment` for a plant in its own loop: each reference is the instrument
    of its own model input (:mod:`fmu_fdi.identify.closed_loop`), so each must reach ``SNR_TARGET``
    on its best-seen output by itself (a reference the loop integrates, like a load torque, would
    otherwise meet the common target alone and leave the others in the noise); raised within
    its limit, never lowered."""
    noisy = sigma > 0
    out = dict(amp)
    for k in free:
        alone = {n: (amp[n] if n == k else 0.0) for n in names}
        r = _predicted_response(rough, exc, names, alone, None, ts, ts0)
        snr = float(np.max(r[noisy] / sigma[noisy]))
        if snr < SNR_TARGET:
            out[k] = min(amp[k] * SNR_TARGET / max(snr, 1e-12), max(limit[k], amp[k]))
    if out != amp:
        notes.append("a plant in its own loop: each reference raised to signal/noise "
                     f"{SNR_TARGET:g} by itself: {', '.join(f'{k} ±{v:.4g}' for k, v in out.items())}")
    return out


def _predicted_response(rough, exc, names, seed_amp, pre, ts, ts0, slow_model=None) -> np.ndarray:
    """Std per output of the rough model's response to ``exc`` (seed amplitudes) on the inputs ``names``.

    The model runs at the pre-test's ts0; a signal designed at ts = k·ts0 is held k steps and
    the response read every k-th sample. Without a model the pre-test's own response std
    stands in. A two-scale PRBS (``exc.slow_period``): the fast half by this model, the slow
    half by ``slow_model`` (the slow pre-test's, at its own sample time: the fast pre-test
    does not see the slow modes), the two independent: r² = r_fast² + r_slow²."""
    if rough is None:
        return (pre.y - pre.y0).std(axis=0)
    if exc.slow_period is not None:
        half = {n: 0.5 * seed_amp[n] for n in names}
        r = _predicted_response(rough, replace(exc, slow_period=None), names, half, pre, ts, ts0)
        if slow_model is None:
            return r
        ts_s = slow_model.dt
        clock = max(1, int(round(exc.slow_period * ts / ts_s)))
        slow = replace(exc, period=clock, slow_period=None, samples=max(int(exc.samples * ts / ts_s), 20 * clock))
        u = excitation_signals(slow, names, [half[n] for n in names])
        y = slow_model.simulate(u)
        return np.sqrt(r ** 2 + y[len(y) // 10:].var(axis=0))
    k = max(1, int(round(ts / ts0)))
    u = np.repeat(excitation_signals(exc, names, [seed_amp[n] for n in names]), k, axis=0)
    y = rough.simulate(u)[::k]
    return y[len(y) // 10:].std(axis=0)


def _least_misfit_model(pre, pre_exc, dy, ts, max_order):
    """The slow pre-test's model: among PO-MOESP's stable candidates of every order (one
    factorisation), the smallest order whose output error (after the first fifth), normalised per
    output by the response's variance and averaged, is within 2 % of the least. On a coarse
    step the fast modes are a sample or less and their ringing aliases: the order the singular
    values' gap gives can pair the slow mode with a spurious one (drive train at ts = 1 s:
    λ = −0.0070 and +0.0016 s⁻¹), whose simulation error gives it away (Ljung 1999, sec. 16.4).
    None when no candidate is stable."""
    from .subspace import least_order_near_best, moesp

    names = list(pre.excited)
    dev = excitation_signals(pre_exc, names, [pre.excited[k] for k in names])
    try:
        cands = moesp(dev, dy, ts, None, max_order=max_order, feedthrough=False, candidates=True)[1:]
    except IdentificationError:
        return None
    scored = []
    var = np.maximum(dy[len(dy) // 5:].var(axis=0), np.finfo(float).tiny)
    for c in cands:
        if np.any(np.abs(np.linalg.eigvals(c.A)) >= 1.0):
            continue
        res = (dy - c.simulate(dev))[len(dy) // 5:]
        scored.append((float(np.mean(res.var(axis=0) / var)), c.order, c))
    if not scored:
        return None
    return least_order_near_best(scored)


def _slow_stages(path, sig, y_names, tau_max, sigma_settle, sigma, *, settle, seed_amp, notes, excite, at,
                 parameters, ts0, seed, limit, given_amp, max_order):
    """Stage of :func:`plan_experiment`: slow modes the pre-test does not see settle.

    The multisine's lowest line is 1/T_pre (T_pre = ``PRETEST_SAMPLES`` · ts), and a mode slower
    than a third of T_pre is not seen to settle: its time scale is a guess, and a mode much
    slower than T_pre (the wind turbine's drive train: 138 s against 10 s) is not seen at all —
    its response is a drift the pre-test model leaves in its misfit. So while the slowest time
    scale found exceeds T_pre/3 and the pre-test model leaves a response unexplained (its misfit
    above ``SLOW_MISFIT`` times the settle phase's noise std on some output: noise coloured
    beyond the settle window raises it a few times — the lateral aircraft 3.2 —, the drive
    train's unseen rotor mode 31 times), the pre-test is repeated with a step ``SLOW_STAGE_FACTOR`` times
    coarser (the same number of samples, that many times longer; at most ``SLOW_STAGES`` times):
    its model's slowest time scale replaces the estimate. Each stage's model misfit is another
    upper bound of the noise (:func:`_with_misfit`); the noise std is the smallest of them (and
    at least ``sigma_settle``, the settle phase's). Returns ``((tau_max, slowest stage's model or None), sigma)``."""
    model = None
    ts_k = ts0
    noisy = sigma_settle > 0
    if not np.any(noisy) or np.max(sigma[noisy] / sigma_settle[noisy]) <= SLOW_MISFIT:
        return (tau_max, None), sigma
    for _ in range(SLOW_STAGES):
        if tau_max <= PRETEST_SAMPLES * ts_k / 3:
            break
        ts_k *= SLOW_STAGE_FACTOR
        try:
            pre, pre_exc, _, dy, _, _ = _pretest(path, sig, y_names, excite=excite, at=at, parameters=parameters,
                                                 ts0=ts_k, settle=max(settle, MIN_SETTLE * ts_k), seed=seed,
                                                 seed_amp=seed_amp, limit=limit, given_amp=dict(seed_amp),
                                                 max_order=max_order)
        except IdentificationError as exc:
            notes.append(f"slow pre-test at ts = {ts_k:g} s failed ({exc})")
            break
        rough = _least_misfit_model(pre, pre_exc, dy, ts_k, max_order)
        if rough is None:
            break
        found = _time_scales(np.linalg.eigvals(rough.A), ts_k)[1]
        notes.append(f"time scale {tau_max:.3g} s not seen settling in the pre-test: repeated at ts = {ts_k:g} s "
                     f"({PRETEST_SAMPLES * ts_k:g} s), slowest time scale {found:.3g} s")
        tau_max, model = found, rough
        sigma = np.minimum(sigma, _with_misfit(sigma_settle, rough, pre, pre_exc, dy))
    return (tau_max, model), sigma
