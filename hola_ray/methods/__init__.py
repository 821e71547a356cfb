"""Training methods as strategies over one trainer: the run config (`config`), the
protocol a method implements (`base`), one module per method (`hola`, `sp`, `fcp`, `mep`,
`pbt`), their registry (`registry`) and the generation loop (`trainer`)."""

from hola_ray.methods import registry
from hola_ray.methods.config import METHODS, RunConfig

__all__ = ["METHODS", "RunConfig", "registry"]
