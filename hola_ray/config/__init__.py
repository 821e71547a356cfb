"""Every config of the project, at the bottom of the house: the one reader (`reader`: YAML
read as numbers, each value checked against its field's type before its range, one
`ConfigError` naming the field, its file and line) and every section's frozen dataclass:
the scenario (`scenario`, with the observation's layout in `layout`), the Oracle
(`oracle`), the population and the Grapher (`population`), pre-training and validation
(`run`). `hola_ray.methods.config.RunConfig` puts a run's sections together with its
method's own; `hola_ray.experiment.config` reads an experiment. Configs travel to Ray's
actors and tasks as the frozen values they are."""

from hola_ray.config.layout import ObsLayout
from hola_ray.config.oracle import BUDGETS, DISTRIBUTIONS, SAMPLERS, OracleConfig, Seating
from hola_ray.config.population import GrapherConfig, PopulationConfig
from hola_ray.config.reader import ConfigError
from hola_ray.config.run import EVALUATION_POOLS, PRETRAIN_SCHEMES, PretrainConfig, ValidationConfig
from hola_ray.config.scenario import EvaderConfig, PursuitConfig, RewardConfig

__all__ = [
    "BUDGETS",
    "DISTRIBUTIONS",
    "EVALUATION_POOLS",
    "PRETRAIN_SCHEMES",
    "SAMPLERS",
    "ConfigError",
    "EvaderConfig",
    "GrapherConfig",
    "ObsLayout",
    "OracleConfig",
    "PopulationConfig",
    "PretrainConfig",
    "PursuitConfig",
    "RewardConfig",
    "Seating",
    "ValidationConfig",
]
