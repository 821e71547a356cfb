"""The population on Ray: evaluation actors, the Grapher, the coordinator, the run directory.

The decisions themselves live in the pure `Population` (no Ray)."""

from hola_ray.population.coordinator import Coordinator, coordinator_name
from hola_ray.population.evaluators import Evaluator, EvaluatorPool, evaluate_team, evaluate_teams
from hola_ray.population.grapher import evaluate_edges
from hola_ray.population.rundir import RunDir
from hola_ray.population.state import Decision, EdgeResult, Population, edge_seed
from hola_ray.process import NAMESPACE

__all__ = [
    "NAMESPACE",
    "Coordinator",
    "Decision",
    "EdgeResult",
    "Evaluator",
    "EvaluatorPool",
    "Population",
    "RunDir",
    "coordinator_name",
    "edge_seed",
    "evaluate_edges",
    "evaluate_team",
    "evaluate_teams",
]
