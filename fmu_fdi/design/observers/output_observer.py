"""Full-order output observer (Luenberger) residual generator by pole placement.

    x̂' = A x̂ + Bu u + L (y − ŷ),     ŷ = C x̂ + Du u,     r = V (y − ŷ)

(Frank, section 5: the diagnostic observer; Chen & Patton 1999, sec. 2.4). The error
``e = x − x̂`` obeys ``e' = (A − L C) e + ... f`` whatever u is, so ``Ru = 0`` and the
residual dynamics are the eigenvalues of ``A − L C``. The unknown inputs d are *not*
decoupled: they drive r like faults (use :func:`~fmu_fdi.design.observers.uio.unknown_input_observer`
or :func:`~fmu_fdi.design.problems.nullspace.nullspace_design` to decouple them).
"""
from __future__ import annotations

import numpy as np

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import rank
from ...model import FDIModel
from ._observer import as_matrix, observer_gain, observer_generator, output_observer, residual_names


def luenberger(model: FDIModel, poles=None, V=None, *, atol: float = 0.0) -> ResidualGenerator:
    """Output-observer residual ``r = V (y − C x̂ − Du u)`` with ``eig(A − L C)`` at ``poles``.

    Parameters
    ----------
    model : FDIModel
        Continuous (the filter is continuous) or discrete (designed directly in discrete
        time, ``x̂[k+1] = A x̂[k] + Bu u[k] + L (y[k] − ŷ[k])``).
    poles : array_like
        Observer poles, closed under conjugation, stable. Exactly as many as ``(A, C)`` has
        observable modes (``n`` for an observable pair); ``None`` picks distinct poles
        twice as fast as the plant's modes (:func:`~fmu_fdi.design.observers._observer.default_poles`).
    V : array_like, optional
        Static output weighting (k × p, default the identity): r has k components.
    atol : float
        Absolute rank tolerance of the observability staircase (Varga's ``atol``): singular values at or
        below ``max(rtol·||[A; C]||, atol)`` count as zero (default 0: relative only).

    Returns
    -------
    ResidualGenerator
        One residual group; ``info``: ``gain`` L, ``poles`` (assigned), ``fixed_modes``
        (unobservable, stable, not assignable), ``placement`` method, ``detected_faults``.

    Raises
    ------
    DesignError
        ``(A, C)`` not detectable (the message names the unstable unobservable modes);
        poles unstable, not finite, not conjugate-closed or of the wrong count; V of the
        wrong shape, not finite, or zero.

    References
    ----------
    D. G. Luenberger, Observing the state of a linear system, IEEE Trans. Mil. Electron. 8, 1964.
    J. Chen and R. J. Patton, *Robust Model-Based Fault Diagnosis for Dynamic Systems*, 1999, sec. 2.4.
    J. Kautsky, N. K. Nichols and P. Van Dooren, Robust pole assignment in linear state feedback,
    Int. J. Control 41, 1985.
    """
    W = None
    if V is not None:
        W = as_matrix(np.atleast_2d(V) if np.ndim(V) < 2 else V, "V", cols=model.ny)
        if rank(W) == 0:
            raise DesignError("V is zero: the weighted residual V (y − ŷ) would be identically zero")
    gain = observer_gain(model.A, model.C, poles, model.dt, what="(A, C)",
                         fixed_reason="an output observer cannot exist (add sensors that see these modes)", atol=atol)
    Q = output_observer(model, gain.L, W)
    info = {"gain": gain.L.tolist(), "poles": gain.poles.tolist(), "fixed_modes": gain.fixed.tolist(),
            "placement": gain.method, "V": (np.eye(model.ny) if W is None else W).tolist()}
    return observer_generator(model, Q, "luenberger", info, residual_names(model, W))
