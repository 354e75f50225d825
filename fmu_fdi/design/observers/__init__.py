"""The classical observer-based residual generators, beside the synthesis problems: Luenberger
(:mod:`.output_observer`), Kalman innovation (:mod:`.kalman_filter`), unknown-input observer
(:mod:`.uio`) and the Beard–Jones fault detection filter (:mod:`.beard_jones`), sharing the
gains, Riccati filters and residual filter of :mod:`._observer`. The package face is
:mod:`fmu_fdi.design`.
"""
