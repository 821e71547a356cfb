"""What a training method is: a strategy over the one trainer (SPEC §5).

A method says how its partner population is built (generation 0), how the Oracle seats
the learner, how partners are drawn from the population (its `Rules`, which the
coordinator asks), who joins the population, and what it does before each generation's
training. The trainer (`hola_ray.methods.trainer`) runs the same generation loop for
every method and asks the method at each of these points; it has no branch on a method's
name. A new method is one module with a `Method` subclass and one line in
`hola_ray.methods.registry` (BenchMARL's algorithm classes and registry are the model).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from hola_ray.oracle import Oracle
from hola_ray.oracle.config import Seating
from hola_ray.population.state import Decision, Population

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.trainer import Trainer
    from hola_ray.oracle.trainer import TrainStats


@dataclass(frozen=True)
class Built:
    """A method's generation 0: the initial members' RLlib states, what building them
    cost, and one line that says how they were built."""

    states: list[dict[str, Any]]
    stats: TrainStats
    said: str


@dataclass(frozen=True)
class Uniform:
    """Rules: partners drawn uniformly from the members; a candidate joins when `admit`
    and its η rank is within the top m."""

    admit: bool = True

    def setup(self, population: Population) -> None:
        pass

    def phi(self, population: Population, exclude_slot: int | None = None) -> dict[int, float]:
        members = population.drawable(exclude_slot)
        return {v: 1.0 / len(members) for v in members}

    def values(self, population: Population) -> dict[int, float | None]:
        return dict.fromkeys(population.members)

    def decide(
        self, population: Population, slot: int | None, rng: np.random.Generator
    ) -> Decision:
        return population.decide(admit=self.admit)


class Method:
    """The protocol every method implements; the defaults are HOLA-Drone's shape: an MEP
    population, the learner in one seat beside partners, and a learner that may join."""

    name: str
    description: str
    self_play: ClassVar[bool] = False
    """the learner in every seat: no population, no pre-training, no Grapher; the learner
    is judged by its own team's rollout"""
    joins: ClassVar[bool] = True
    """the learner may join the population (False: a best response to a fixed one)"""
    shares_generation_zero: ClassVar[bool] = False
    """generation 0 is MEP's population, the same for every method that says so: one run
    may adopt another's (`RunConfig.generation_zero_key`)"""
    section: ClassVar[tuple[str, type] | None] = None
    """the method's own run-config section (name, frozen dataclass with `validate()`), or
    None; `config.<name>` reads it"""

    def __init__(self, name: str, description: str):
        self.name, self.description = name, description

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"

    # ---- configuration ------------------------------------------------------------------
    def validate(self, config: RunConfig) -> None:
        """Checks that span sections (ConfigError naming the field)."""

    def seating(self, config: RunConfig) -> Seating:
        """How the Oracle seats the learner each generation."""
        if self.self_play:
            return Seating()
        return Seating(partners=config.population.max_size)

    def rules(self, config: RunConfig) -> Any:
        """The coordinator's `Rules` for this run (`hola_ray.population.rules`)."""
        return Uniform(admit=self.joins)

    # ---- the generation loop ------------------------------------------------------------
    def build_population(self, trainer: Trainer) -> Built:
        """Generation 0: the initial members (default: MEP pre-training)."""
        return pretrain_jointly(trainer, trainer.config.pretrain.alpha, "with MEP")

    def before_training(self, trainer: Trainer, g: int, oracle: Oracle) -> int | None:
        """Called before generation g's Oracle trains; returns the population slot of the
        member the learner was seated from (PBT), else None."""
        return None

    def verdict(self, config: RunConfig, decision: Decision) -> str:
        """What the generation's log line says about the coordinator's decision."""
        if decision.accepted:
            return f"accepted as node {decision.candidate} (rank {decision.rank}" + (
                f", replaces {decision.replaced})" if decision.replaced is not None else ")"
            )
        if not self.joins:
            return f"population fixed ({self.name}: a best response; η rank {decision.rank})"
        return f"rejected (rank {decision.rank} > top {config.population.top_m})"


def pretrain_jointly(trainer: Trainer, alpha: float, how: str) -> Built:
    """`population.initial_size` members trained jointly for `pretrain.env_steps`, with
    MEP's population-entropy bonus of weight `alpha` (0: plain joint training)."""
    c = trainer.config
    n = c.population.initial_size
    mep = Oracle(c.env, c.oracle, Seating(mep_members=n, mep_alpha=alpha), c.seed)
    try:
        stats = mep.train(c.pretrain.env_steps, desc="pre-train (MEP)", progress=trainer.progress)
        states = mep.weights(mep.members)
    finally:
        mep.stop()
    return Built([states[m] for m in mep.members], stats, f"pre-trained {n} members {how}")
