"""The hypergraphic-form game (docs/contract.md §4): pure numpy, no Ray."""

from hola_ray.hypergraph.hyfog import HyFoG, HyFoGError, Hyperedge
from hola_ray.hypergraph.myerson import coalition_values, myerson_sample, myerson_value
from hola_ray.hypergraph.phi import inverse_shifted, node_values, phi
from hola_ray.hypergraph.preference import (
    centrality,
    in_degree,
    lowest_centrality,
    preference_hypergraph,
    rank_of,
    ranking,
    within_top,
)

__all__ = [
    "HyFoG",
    "HyFoGError",
    "Hyperedge",
    "centrality",
    "coalition_values",
    "in_degree",
    "inverse_shifted",
    "lowest_centrality",
    "myerson_sample",
    "myerson_value",
    "node_values",
    "phi",
    "preference_hypergraph",
    "rank_of",
    "ranking",
    "within_top",
]
