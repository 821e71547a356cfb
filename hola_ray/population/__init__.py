"""The population on Ray: member actors, the Grapher, the coordinator, the run directory.

The decisions themselves live in the pure `Population` (no Ray)."""

from hola_ray.population.coordinator import Coordinator, coordinator_name
from hola_ray.population.grapher import evaluate_edges
from hola_ray.population.member import Member, MemberPool, evaluate_team
from hola_ray.population.rundir import RunDir
from hola_ray.population.state import Decision, EdgeResult, Population, edge_seed
from hola_ray.progress import NAMESPACE

__all__ = [
    "NAMESPACE",
    "Coordinator",
    "Decision",
    "EdgeResult",
    "Member",
    "MemberPool",
    "Population",
    "RunDir",
    "coordinator_name",
    "edge_seed",
    "evaluate_edges",
    "evaluate_team",
]
