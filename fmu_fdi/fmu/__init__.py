"""The diagnostic FMU: pythonfmu slave base, packaging, modelDescription post-processing, hosts.

Modules bundled *into* FMUs (``slave_base``, ``slave_state``) import only numpy, the standard
library and pythonfmu; the others run in the building or hosting process.
"""
