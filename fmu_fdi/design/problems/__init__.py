"""One module per synthesis problem (Varga 2017; Ding 2014; Frank 1990), each a public design
function returning a ResidualGenerator or ResidualBank: exact and approximate fault detection
by null space (:mod:`.nullspace`), parity space (:mod:`.parity`), isolation banks
(:mod:`.banks`), exact and approximate model matching (:mod:`.matching`,
:mod:`.approximate_matching`), model detection (:mod:`.model_detection`), the factorised form
(:mod:`.coprime`), the mixed H−/H∞ solution (:mod:`.unified`), data-driven parity
(:mod:`.datadriven`) and parameter estimation (:mod:`.rls`). They stand on
:mod:`fmu_fdi.design.toolkit`; the package face is :mod:`fmu_fdi.design`.
"""
