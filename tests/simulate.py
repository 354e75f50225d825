"""Exact simulation of plant + residual generator for tests.

The plant ``Ge = [G; I 0 0 0]`` (from [u; d; w; f] to [y; u]) and the filter Q are put in
series *without* any cancellation (``Q @ Ge`` keeps every plant and filter state) and the
cascade is discretised with a zero-order hold of the plant inputs. For piecewise-constant
inputs that is the exact sampled response of the continuous (or discrete) interconnection,
so a residual that must vanish is only rounding away from zero.
"""
import numpy as np


def _inputs(model, N, u, d, w, f) -> np.ndarray:
    """[u d w f] samples (N × channels), missing groups zero."""
    sig = []
    for arr, k in ((u, model.nu), (d, model.nd), (w, model.nw), (f, model.nf)):
        sig.append(np.zeros((N, k)) if arr is None else np.asarray(arr, float).reshape(N, k))
    return np.hstack(sig)


def _run(sys, Ts, v, x0=None) -> np.ndarray:
    """Outputs of a (continuous → ZOH-discretised, or discrete) system driven by rows of v."""
    if not sys.is_discrete:
        if Ts is None:
            raise ValueError("Ts is needed for a continuous model")
        sys = sys.to_discrete(Ts)
    x = np.zeros(sys.n) if x0 is None else x0
    out = np.empty((v.shape[0], sys.p))
    for k in range(v.shape[0]):
        out[k] = sys.C @ x + sys.D @ v[k]
        x = sys.A @ x + sys.B @ v[k]
    return out


def cascade_residual(gen, N, Ts=None, u=None, d=None, w=None, f=None, x0_plant=None):
    """Residual samples (N × n_r) of generator ``gen`` driven by its own model.

    Inputs are arrays (N × channels) held constant over each sample; missing groups are 0.
    ``Ts`` is required for a continuous model. ``x0_plant`` sets the plant's initial state.
    """
    m = gen.model
    cascade = gen.Q @ m.augmented()  # states: plant first, then filter
    x0 = None
    if x0_plant is not None:
        x0 = np.zeros(cascade.n)
        x0[: m.n] = x0_plant
    return _run(cascade, Ts, _inputs(m, N, u, d, w, f), x0)


def plant_outputs(model, N, Ts=None, u=None, d=None, w=None, f=None):
    """Plant outputs y (N × ny) under the same ZOH inputs (for signal-size references)."""
    return _run(model.lti(), Ts, _inputs(model, N, u, d, w, f))
