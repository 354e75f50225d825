"""The one object every design returns: a residual generator and its internal form.

A residual generator is an LTI filter ``r = Q(λ) [y; u]`` (Frank, eq. 8:
``r = P u + Q y`` with ``P = -Q Gu`` for an exact generator, eq. 9). Its *internal form*
is the transfer from every plant input to the residual,

    R(λ) = Q(λ) [Gu Gd Gw Gf; I 0 0 0] = [Ru Rd Rw Rf],

which is what decoupling (``Ru = Rd = 0``), structure matrices and gaps are read from.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from .lti import LTI, structurally_observed, vstack
from .margin import default_smarg, margin_reduced
from .model import FDIModel


class ResidualGenerator:
    """An LTI residual filter from ``[y; u]`` to ``r`` together with its design model.

    Attributes
    ----------
    Q : LTI
        The filter; inputs are the model's outputs then its known inputs.
    model : FDIModel
        The model the filter was designed for (its internal form is computed against it).
    method : str
        Name of the design method.
    residual_names : list of str
        One name per residual component.
    groups : list of list of int
        Residual components evaluated together (one group per residual vector, e.g. one
        per member of a bank). Structure matrices and alarms are per group.
    info : dict
        Method-specific results (poles, degrees, gaps, fault directions, ...).
    continuous : ResidualGenerator or None
        For a generator obtained by :meth:`to_discrete`, the continuous design it came from.
    """

    def __init__(self, Q: LTI, model: FDIModel, method: str, residual_names=None, groups=None,
                 info: dict | None = None, continuous: "ResidualGenerator | None" = None):
        if Q.m != model.ny + model.nu:
            raise ValueError(
                f"residual filter has {Q.m} inputs but the model has {model.ny} outputs + {model.nu} inputs"
            )
        if abs(Q.dt - model.dt) > 1e-12 * max(1.0, model.dt):
            raise ValueError(f"filter sample time {Q.dt} differs from the model's {model.dt}")
        self.Q = Q
        self.model = model
        self.method = method
        self.residual_names = list(residual_names or [f"r{k + 1}" for k in range(Q.p)])
        if len(self.residual_names) != Q.p:
            raise ValueError(f"{len(self.residual_names)} residual names for {Q.p} residuals")
        self.groups = [list(g) for g in (groups or [[k] for k in range(Q.p)])]
        flat = sorted(i for g in self.groups for i in g)
        if flat != list(range(Q.p)):
            raise ValueError(f"residual groups {self.groups} must partition 0..{Q.p - 1}")
        self.info = dict(info or {})
        self.continuous = continuous

    # ------------------------------------------------------------------ basics
    @property
    def dt(self) -> float:
        return self.Q.dt

    @property
    def input_names(self) -> list[str]:
        return list(self.model.y_names) + list(self.model.u_names)

    @property
    def n_residuals(self) -> int:
        return self.Q.p

    def __repr__(self) -> str:
        return (f"ResidualGenerator(method='{self.method}', residuals={self.Q.p}, order={self.Q.n}, "
                f"{'dt=' + format(self.dt, 'g') if self.dt else 'continuous'})")

    def scale_rows(self, scales) -> None:
        """Scale residual component k by ``scales[k]`` (``Q ← diag(scales) Q``; a bank's members
        follow): the normalisation of :func:`~fmu_fdi.design.toolkit.postconditions.check_generator`."""
        s = np.asarray(scales, float).reshape(-1)
        if s.size != self.Q.p or not np.all(np.isfinite(s)) or np.any(s == 0):
            raise ValueError(f"row scales must be {self.Q.p} finite non-zero numbers, got {s.tolist()}")
        Q = self.Q
        self.Q = LTI(Q.A, Q.B, s[:, None] * Q.C, s[:, None] * Q.D, Q.dt)
        self.__dict__.pop("_R", None)
        self.__dict__.pop("_blocks", None)
        self.__dict__.pop("_group_R", None)
        for g, member in zip(self.groups, getattr(self, "members", ())):
            member.scale_rows(s[g])

    # ----------------------------------------------------------- internal form
    @cached_property
    def _R(self) -> LTI:
        return self._minimal_internal_form(self.Q)

    def _minimal_internal_form(self, Q: LTI) -> LTI:
        """The minimal realisation of ``Q·[Gu Gd Gw Gf; I 0 0 0]`` for this generator's model."""
        # the plant modes outside the stability margin that Q cancels go first, with the judge's
        # tolerance (margin.margin_reduced): TB01PD's own tolerance kept Ex. 5.4's
        # cancelled poles 2, 3 in Rf
        T = Q @ self.model.augmented()
        try:
            T = margin_reduced(T, default_smarg(self.dt))
        except (np.linalg.LinAlgError, ValueError):  # a Sylvester equation with a pole on the margin
            pass
        return T.minreal()

    def group_internal_form(self, i: int) -> LTI:
        """``R_g = Q_g·[Gu Gd Gw Gf; I 0 0 0]`` for the rows ``g`` of residual group ``i``: the rows ``g`` of
        :attr:`_R` (always for a single group), or, where those rows of Q do not observe every state of Q by its exact zero pattern
        (:func:`~fmu_fdi.lti.structurally_observed`: a bank's group sees only its own member's states), the minimal
        realisation of ``Q_g·Ge`` built on the states they observe.

        The same transfer function either way. Rows of the stacked bank's :attr:`_R` keep the other
        members' states, which the minimal realisation of a row slice does not remove (afdi seed 78:
        rows of 162 states where the member's own internal form has 71).
        """
        g = self.groups[i]
        keep = structurally_observed(self.Q.A, self.Q.C[g, :])
        if len(g) == self.Q.p or len(keep) == self.Q.n:
            return self._R[g, :]
        cache = self.__dict__.setdefault("_group_R", {})
        if i not in cache:
            Q = self.Q
            cache[i] = self._minimal_internal_form(LTI(Q.A[np.ix_(keep, keep)], Q.B[keep, :], Q.C[np.ix_(g, keep)],
                                                       Q.D[g, :], Q.dt))
        return cache[i]

    def _block(self, group: str) -> LTI:
        """``R[:, group's columns]`` of the one realisation :attr:`_R`, reduced to a minimal realisation
        once and kept (``scale_rows`` forgets them with ``_R``): ``Rf`` alone no longer reduces the u, d
        and w blocks too."""
        cache = self.__dict__.setdefault("_blocks", {})
        if group not in cache:
            cache[group] = self._R[:, self.model.group_slices()[group]].minreal()
        return cache[group]

    def internal_form(self) -> dict[str, LTI]:
        """``{'u': Ru, 'd': Rd, 'w': Rw, 'f': Rf}``, minimal realisations of column slices of the one
        minimal realisation of ``R = Q·[Gu Gd Gw Gf; I 0 0 0]``."""
        return {g: self._block(g) for g in self.model.group_slices()}

    @property
    def Ru(self) -> LTI:
        return self._block("u")

    @property
    def Rd(self) -> LTI:
        return self._block("d")

    @property
    def Rw(self) -> LTI:
        return self._block("w")

    @property
    def Rf(self) -> LTI:
        return self._block("f")

    def fault_response(self, fault: str | int) -> LTI:
        """Transfer from one named fault (all its columns) to the residual."""
        spec = self.model.faults[fault] if isinstance(fault, int) else self.model.fault(fault)
        sl = self.model.group_slices()["f"]
        cols = np.arange(sl.start, sl.stop)[spec.columns]
        return self._R[:, cols].minreal()

    # --------------------------------------------------------------- sampling
    def to_discrete(self, Ts: float) -> "ResidualGenerator":
        """Exact zero-order-hold discretisation of the filter for sample time ``Ts``.

        The filter's inputs ``[y; u]`` are held over each sample. The internal form of
        the result is taken against the model discretised the same way (ZOH of u, d, w,
        f); for a design on sampled data with exact decoupling at the samples, design
        directly on ``model.discretize(Ts)`` instead.
        """
        if self.dt:
            raise ValueError(f"generator is already discrete (dt={self.dt})")
        return type(self)._rebuild(self, self.Q.to_discrete(Ts), self.model.discretize(Ts))

    @staticmethod
    def _rebuild(gen: "ResidualGenerator", Q: LTI, model: FDIModel) -> "ResidualGenerator":
        out = ResidualGenerator(Q, model, gen.method, gen.residual_names, gen.groups, gen.info,
                                continuous=gen if not gen.dt else gen.continuous)
        return out

    def runtime_spec(self) -> dict:
        """The discrete filter as the numpy runtime reads it (see :mod:`fmu_fdi.runtime`)."""
        if not self.dt:
            raise ValueError("the runtime needs a discrete generator: call to_discrete(Ts) first")
        Q = self.Q
        return {"kind": "lti", "A": Q.A.tolist(), "B": Q.B.tolist(), "C": Q.C.tolist(), "D": Q.D.tolist(),
                "dt": Q.dt}

    def simulate(self, y, u, x0=None) -> np.ndarray:
        """Residuals of a discrete generator for sampled ``y`` (N×ny) and ``u`` (N×nu)."""
        if not self.dt:
            raise ValueError("simulate() needs a discrete generator: call to_discrete(Ts) first")
        from .runtime.lti_filter import simulate_lti

        v = np.hstack([np.atleast_2d(y).reshape(len(y), -1), np.asarray(u, float).reshape(len(y), -1)])
        return simulate_lti(self.Q.A, self.Q.B, self.Q.C, self.Q.D, v, x0)


class ResidualBank(ResidualGenerator):
    """A bank of residual generators evaluated side by side (DOS, GOS, structured).

    The stacked filter is ``Q = [Q_1; Q_2; ...]``; member i forms residual group i.
    ``info['structure']`` holds the structure matrix the bank was designed for.
    """

    def __init__(self, members: list[ResidualGenerator], method: str, info: dict | None = None):
        if not members:
            raise ValueError("a bank needs at least one member")
        model = members[0].model
        Q = vstack([g.Q for g in members])
        names, groups, k = [], [], 0
        for i, g in enumerate(members):
            if g.Q.p == 1:
                names.append(f"r{i + 1}")
            else:
                names.extend(f"r{i + 1}_{j + 1}" for j in range(g.Q.p))
            groups.append(list(range(k, k + g.Q.p)))
            k += g.Q.p
        super().__init__(Q, model, method, names, groups, info)
        self.members = members

    @staticmethod
    def _rebuild(gen, Q, model):
        members = [ResidualGenerator._rebuild(g, g.Q.to_discrete(Q.dt), model) for g in gen.members]
        out = ResidualBank(members, gen.method, gen.info)
        out.continuous = gen if not gen.dt else gen.continuous
        return out
