"""Exact simulation of plant + residual generator for tests.

The plant ``Ge = [G; I 0 0 0]`` (from [u; d; w; f] to [y; u]) and the filter Q are put in
series *without* any cancellation (``Q @ Ge`` keeps every plant and filter state) and the
cascade is discretised with a zero-order hold of the plant inputs. For piecewise-constant
inputs that is the exact sampled response of the continuous (or discrete) interconnection,
so a residual that must vanish is only rounding away from zero.
"""
import numpy as np

from fmu_fdi.lti import LTI


def cascade_residual(gen, N, Ts=None, u=None, d=None, w=None, f=None, x0_plant=None):
    """Residual samples (N × n_r) of generator ``gen`` driven by its own model.

    Inputs are arrays (N × channels) held constant over each sample; missing groups are 0.
    ``Ts`` is required for a continuous model. ``x0_plant`` sets the plant's initial state.
    """
    m = gen.model
    cascade = gen.Q @ m.augmented()  # states: plant first, then filter
    if not cascade.is_discrete:
        if Ts is None:
            raise ValueError("Ts is needed for a continuous model")
        cascade = cascade.to_discrete(Ts)
    sig = []
    for arr, k in ((u, m.nu), (d, m.nd), (w, m.nw), (f, m.nf)):
        sig.append(np.zeros((N, k)) if arr is None else np.asarray(arr, float).reshape(N, k))
    v = np.hstack(sig)
    x = np.zeros(cascade.n)
    if x0_plant is not None:
        x[: m.n] = x0_plant
    out = np.empty((N, cascade.p))
    for k in range(N):
        out[k] = cascade.C @ x + cascade.D @ v[k]
        x = cascade.A @ x + cascade.B @ v[k]
    return out


def plant_outputs(model, N, Ts=None, u=None, d=None, w=None, f=None):
    """Plant outputs y (N × ny) under the same ZOH inputs (for signal-size references)."""
    G = model.lti()
    if not G.is_discrete:
        G = G.to_discrete(Ts)
    sig = []
    for arr, k in ((u, model.nu), (d, model.nd), (w, model.nw), (f, model.nf)):
        sig.append(np.zeros((N, k)) if arr is None else np.asarray(arr, float).reshape(N, k))
    v = np.hstack(sig)
    x = np.zeros(G.n)
    out = np.empty((N, G.p))
    for k in range(N):
        out[k] = G.C @ x + G.D @ v[k]
        x = G.A @ x + G.B @ v[k]
    return out
