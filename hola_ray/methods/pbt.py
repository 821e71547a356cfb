"""Population-based training (Jaderberg et al. 2017, as Carroll et al. 2019 use it): the
initial agents are trained jointly with each other (MEP's pre-training without its
entropy bonus); then each generation trains one agent in turn, with partners drawn
uniformly from the others, and it replaces its earlier self. Once every agent has a score,
an agent in the bottom quantile exploits (copies an agent from the top quantile) and
explores (perturbs that agent's lr and entropy coefficient)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import ray

from hola_ray.config.reader import finite_in, require
from hola_ray.config.run import PRETRAIN_SCHEMES
from hola_ray.methods.base import Method, Origin
from hola_ray.methods.context import Context
from hola_ray.methods.pretrain import Built, pretrain_population
from hola_ray.oracle.mapping import LEARNER
from hola_ray.population.rules import ExploitExplore
from hola_ray.population.state import Decision

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig
    from hola_ray.oracle.trainer import Oracle


RANDOM = "random"
"""`pbt.start`: the agents are copies of the learner's random weights, untrained"""


@dataclass(frozen=True)
class PBTConfig:
    """Population-based training's exploit and explore (method pbt). Each generation
    trains one agent, in turn, with partners drawn uniformly from the other agents; it then
    replaces its earlier self."""

    quantile: float = 0.25
    """an agent scoring in the bottom quantile copies one from the top quantile (exploit)"""
    perturb: tuple[float, ...] = (0.8, 1.2)
    """and multiplies that agent's lr and entropy coefficient by a factor drawn from these
    (explore)"""
    start: str = "mixed"
    """how the initial agents train (generation 0, no entropy bonus): mixed, jointly in
    teams drawn from all of them (PBT's start); self-play, each in its own copies' team
    (the shipped pbt populations: competent agents, as MEP's self-play scheme at α 0);
    random, none: each a copy of the learner's random weights at the run's seed, the
    weights every other method's learner starts from (`pretrain.learner_start: random`),
    so that PBT shares a comparison's common random start"""

    def validate(self) -> None:
        finite_in("pbt", self, "quantile", 0.01, 0.5, "in [0.01, 0.5]")
        ok = len(self.perturb) >= 1 and all(
            isinstance(f, int | float) and 0 < f < 10 for f in self.perturb
        )
        require(ok, "pbt.perturb", "a non-empty list of factors in (0, 10)", self.perturb)
        starts = (*PRETRAIN_SCHEMES, RANDOM)
        require(self.start in starts, "pbt.start", " or ".join(starts), self.start)


class PBT(Method):
    section = ("pbt", PBTConfig)
    origin: ClassVar[Origin] = Origin(kind="pbt", also=("mep",), sets_learner=True)
    """also: MEP's members, trained with its entropy bonus, as the agents PBT starts from"""

    def validate(self, config: RunConfig) -> None:
        if config.pbt.start != RANDOM:
            return
        p = config.pretrain
        require(
            p.population == "none" and p.start_agent == "none",
            "pbt.start",
            "not random with a population or a start agent (random builds its agents: "
            "pretrain.population and pretrain.start_agent none)",
            config.pbt.start,
        )

    def rules(self, config: RunConfig) -> ExploitExplore:
        o = config.oracle
        return ExploitExplore(config.pbt.quantile, config.pbt.perturb, o.lr, o.entropy_coef)

    def build_population(self, ctx: Context) -> Built:
        c = ctx.config
        n = c.population.initial_size
        if c.pretrain.start_agent != "none":  # the common start: its agents are copies of it
            from hola_ray.methods.generation_zero import start_agent

            _, state, named = start_agent(c)
        elif c.pbt.start == RANDOM:  # the common random start: any method's learner's weights
            oracle = self.make_oracle(c)
            try:
                state = oracle.weights([LEARNER])[LEARNER]
            finally:
                oracle.stop()
            named = f"the learner's random weights at seed {c.seed}"
        else:
            mixed = c.pbt.start == "mixed"
            how = "jointly (PBT's start)" if mixed else "each in self-play (PBT's start)"
            return pretrain_population(ctx, 0.0, how, c.pbt.start)
        from hola_ray.oracle.stats import TrainStats

        return Built([state] * n, TrainStats.untrained(), f"{n} agents, each a copy of {named}")

    def before_training(self, ctx: Context, g: int, oracle: Oracle) -> int:
        """Generation g trains agent (g − 1) mod K: its weights go into the learner, which
        trains with that agent's lr and entropy coefficient and a fresh optimizer."""
        slots = ray.get(ctx.coord.slots.remote())
        slot = (g - 1) % len(slots)
        node = next(v for v, s in slots.items() if s == slot)
        state = ctx.member_states([node])[node]
        oracle.set_trained_weights({LEARNER: state})
        hyper = ray.get(ctx.coord.agent_hyper.remote(slot))
        oracle.reset_learner(hyper["lr"], hyper["entropy_coef"])
        return slot

    def verdict(self, config: RunConfig, decision: Decision) -> str:
        return f"agent {decision.slot} is node {decision.candidate}" + (
            f"; it exploits node {decision.copied_from} and explores lr and entropy"
            if decision.copied_from is not None
            else ""
        )


METHOD = PBT(
    "pbt", "PBT: agents trained in turn with the others, exploit and explore (lr, entropy)"
)
