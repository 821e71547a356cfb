"""hola_ray: HOLA-Drone, hypergraphic open-ended learning for zero-shot multi-drone
cooperative pursuit, on Ray.

A citation "contract §N" (or docs/contract.md §N) in this package is section N of
docs/contract.md: the scenario, the algorithm and the metrics the code implements.
"""
