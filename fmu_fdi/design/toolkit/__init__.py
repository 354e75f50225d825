"""The state-space toolkit the synthesis problems stand on (Varga 2017, ch. 7 and 10).

Minimal polynomial bases of the left null space (:mod:`._basis`) and the proper stable basis
from the system pencil (:mod:`.pencil`); the choice of basis combinations (:mod:`._select`);
the stable left coprime factorisation
of the internal form (:mod:`.stable_factor`); the co-outer–co-inner factorisation and gap
objective of approximate decoupling (:mod:`.approximate`); the numerator refinement
(:mod:`.refine`); and the one judge of every design, the post-conditions on the normalised
internal form (:mod:`.postconditions`, a layer of its own below the rest: ``fmu_fdi/_layers.py``).
No module here imports a problem or an observer.
"""
