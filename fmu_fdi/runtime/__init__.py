"""numpy-only step logic shared by ``Diagnoser.step``/``run`` and the diagnostic FMU.

Nothing in this package may import scipy, control or anything outside itself except
numpy and the standard library: the FMU bundles it as it is, under its own name, and
imports it with relative imports only.
"""
