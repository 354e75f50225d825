"""Decision logic: alarms, persistence, latching and fault isolation (Frank, section 7).

Per residual group i the raw test is ``J_i(k) ≥ J_th,i(k)`` (as Varga's FDSystem).
With persistence (k of n) the alarm rises when at least k of the last n raw tests
fired; a latched alarm stays up until reset. ``fault_detected`` is any alarm.

Isolation:

- ``structure``: the alarm pattern is matched against the columns of the structure
  matrix S (groups × faults); a fault is isolated when exactly one column matches.
  No alarm gives 0; no or several matching columns give -1 (status 'unknown' or
  'several').
- ``direction`` (Beard–Jones fault detection filter): the residual direction is compared
  with each fault's output direction; the closest fault is isolated when the angle gap
  to the second closest is at least ``min_margin`` (radians); the margin is reported.
- ``none``: detection only (isolated index stays 0/-1 = unknown when alarmed).
"""
from __future__ import annotations

import math

import numpy as np

ISOLATION = ("structure", "direction", "none")


class Decision:
    def __init__(self, spec: dict, n_groups: int, n_faults: int):
        self.n_groups, self.n_faults = n_groups, n_faults
        pers = spec.get("persistence", [1, 1])
        self.k_of, self.n_of = int(pers[0]), int(pers[1])
        if not 1 <= self.k_of <= self.n_of:
            raise ValueError(f"persistence must be [k, n] with 1 <= k <= n, got {pers}")
        self.latch = bool(spec.get("latch", False))
        self.mode = spec.get("isolation", "none")
        if self.mode not in ISOLATION:
            raise ValueError(f"unknown isolation {self.mode!r}; use one of {ISOLATION}")
        self.S = None
        if self.mode == "structure":
            S = np.asarray(spec["structure"], dtype=int)
            if S.shape != (n_groups, n_faults):
                raise ValueError(f"structure matrix must be {n_groups}x{n_faults} (groups x faults), got {S.shape}")
            self.S = S.astype(bool)
        if self.mode == "direction":
            D = np.asarray(spec["directions"], float)
            if D.ndim != 2 or D.shape[1] != n_faults:
                raise ValueError(f"fault directions must be (residuals x {n_faults}), got {D.shape}")
            norms = np.linalg.norm(D, axis=0)
            if not np.any(norms > 0):
                raise ValueError("every fault direction is zero: nothing to isolate by direction")
            # a zero column marks a fault without a fixed direction: never chosen
            self.valid = norms > 0
            self.D = D / np.where(self.valid, norms, 1.0)
            self.min_margin = float(spec.get("min_margin", 0.1))
        self.reset()

    def reset(self) -> None:
        self.raw_hist = [[False] * self.n_of for _ in range(self.n_groups)]
        self.alarms = [False] * self.n_groups
        self.latched = [False] * self.n_groups
        self.isolated = 0
        self.status = "none"
        self.margin = float("nan")

    def get_state(self) -> dict:
        return {"raw_hist": [list(h) for h in self.raw_hist], "alarms": list(self.alarms),
                "latched": list(self.latched), "isolated": self.isolated, "status": self.status,
                "margin": self.margin}

    def set_state(self, s: dict) -> None:
        """Restore :meth:`get_state`; ValueError (nothing changed) for a state of another shape."""
        raw_hist = [list(map(bool, h)) for h in s["raw_hist"]]
        alarms, latched = list(map(bool, s["alarms"])), list(map(bool, s["latched"]))
        isolated = int(s["isolated"])
        ng = self.n_groups
        # the common case (persistence [1, 1], no latch) keeps one-entry histories
        if (len(raw_hist) != ng or any(len(h) != self.n_of for h in raw_hist) or len(alarms) != ng
                or len(latched) != ng or not -1 <= isolated <= self.n_faults):
            raise ValueError(f"decision state does not fit {ng} groups with persistence [{self.k_of}, {self.n_of}] "
                             f"and {self.n_faults} faults")
        for h, alarm, latched_g in zip(raw_hist, alarms, latched):  # alarms as persistence and latch make them
            up = sum(h) >= self.k_of
            if (alarm != latched_g or (up and not latched_g)) if self.latch else (latched_g or alarm != up):
                raise ValueError(f"decision state: alarms {alarms} do not follow from the raw tests with "
                                 f"persistence [{self.k_of}, {self.n_of}]" + (" and latch" if self.latch else ""))
        before = self.get_state()
        self.raw_hist, self.alarms, self.latched, self.isolated = raw_hist, alarms, latched, isolated
        self.status = str(s["status"])
        self.margin = float(s["margin"])
        if not self._isolation_fits():
            self.set_state(before)
            raise ValueError(f"decision state: isolated fault {isolated} does not fit the alarms {alarms} "
                             f"({self.mode} isolation)")

    def _structure_isolated(self) -> tuple[int, str]:
        """The fault whose column of S equals the alarm pattern (1-based), else -1 (none or several)."""
        pattern = np.array(self.alarms)
        matches = np.flatnonzero(np.all(self.S == pattern[:, None], axis=0))
        if matches.size == 1:
            return int(matches[0]) + 1, "isolated"
        return -1, "several" if matches.size > 1 else "unknown"

    def _isolation_fits(self) -> bool:
        """isolated_fault as the isolation makes it from the alarms: 0 without an alarm; with one,
        the structure isolation of the pattern, a fault with a direction or -1 (direction), -1 (none)."""
        iso = self.isolated
        if not any(self.alarms):
            return iso == 0
        if self.mode == "structure":
            return iso == self._structure_isolated()[0]
        if self.mode == "direction":
            return iso == -1 or (1 <= iso <= self.n_faults and bool(self.valid[iso - 1]))
        return iso == -1

    def step(self, evaluations, thresholds, residual) -> None:
        """``evaluations``/``thresholds``: per group; ``residual``: the residual vector."""
        self.step_fired([e >= t for e, t in zip(evaluations, thresholds)], residual)

    def step_fired(self, fired, residual) -> None:
        """One sub-sample with the raw tests ``fired`` (per group, bool) given directly;
        ``residual`` None: its direction is unknown (an overflowed sub-sample, docs/semantics.md
        §8), so direction isolation answers -1 when alarmed."""
        if self.n_of == 1 and not self.latch:  # the common case: alarm = raw test
            self.alarms = [bool(f) for f in fired]
            self.raw_hist = [[a] for a in self.alarms]
            self._isolate(residual)
            return
        for i in range(self.n_groups):
            h = self.raw_hist[i]
            h.pop(0)
            h.append(bool(fired[i]))
            up = sum(h) >= self.k_of
            if self.latch:
                self.latched[i] = self.latched[i] or up
                up = self.latched[i]
            self.alarms[i] = up
        self._isolate(residual)

    def _isolate(self, residual: np.ndarray) -> None:
        self.margin = float("nan")
        if not any(self.alarms):
            self.isolated, self.status = 0, "none"
            return
        if self.mode == "structure":
            self.isolated, self.status = self._structure_isolated()
        elif self.mode == "direction":
            if residual is None:
                self.isolated, self.status = -1, "unknown"
                return
            residual = np.asarray(residual, float)
            nr = float(np.linalg.norm(residual))
            if nr == 0.0:
                self.isolated, self.status = -1, "unknown"
                return
            cosines = np.clip(np.abs(self.D.T @ residual) / nr, 0.0, 1.0)
            angles = np.where(self.valid, np.arccos(cosines), np.inf)
            order = np.argsort(angles, kind="stable")
            second = angles[order[1]] if angles.size > 1 and np.isfinite(angles[order[1]]) else math.pi / 2
            self.margin = float(second - angles[order[0]])
            if self.margin >= self.min_margin:
                self.isolated, self.status = int(order[0]) + 1, "isolated"
            else:
                self.isolated, self.status = -1, "unknown"
        else:
            self.isolated, self.status = -1, "unknown"
