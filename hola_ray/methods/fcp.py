"""Fictitious Co-Play (Strouse et al. 2021): a best response to frozen self-play
checkpoints, drawn uniformly. The population is `fcp.agents` self-play agents, each from
its own seed, frozen at the start, the middle and the end of its training."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

from hola_ray.config.oracle import Seating
from hola_ray.config.reader import positive_int, require
from hola_ray.methods.base import Method, Origin
from hola_ray.methods.context import Context
from hola_ray.methods.pretrain import Built, summed
from hola_ray.oracle.mapping import LEARNER

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig


@dataclass(frozen=True)
class FCPConfig:
    """Fictitious Co-Play's partner population (method fcp; Strouse et al. 2021)."""

    agents: int = 2
    """self-play agents, each from its own seed; each gives 3 members (its start, middle
    and end checkpoints), so population.max_size must hold 3 · agents"""
    env_steps: int = 100_000
    """environment steps of each agent's self-play training"""

    def validate(self) -> None:
        positive_int("fcp", self, "agents", maximum=100)
        positive_int("fcp", self, "env_steps", maximum=10**11)


class FCP(Method):
    origin: ClassVar[Origin] = Origin(kind="fcp")
    section = ("fcp", FCPConfig)

    def may_join(self) -> bool:
        return False

    def member_roles(self, nodes: list[int]) -> dict[int, str]:
        """Its agents' start, middle and end checkpoints, in node order."""
        parts = ("start", "middle", "end")
        return {v: f"checkpoint-{parts[k % 3]}" for k, v in enumerate(sorted(nodes))}

    def population_size(self, config: RunConfig) -> int:
        return 3 * config.fcp.agents

    def validate(self, config: RunConfig) -> None:
        members = 3 * config.fcp.agents
        require(
            config.l <= members <= config.population.max_size,
            "fcp.agents",
            f"such that l = {config.l} <= 3 · fcp.agents <= population.max_size "
            f"({config.population.max_size})",
            config.fcp.agents,
        )

    def build_population(self, ctx: Context) -> Built:
        from hola_ray.oracle.trainer import Oracle

        c = ctx.config
        # FCP's partners, like MEP's, are built in environment steps (`fcp.env_steps`)
        oracle_config = dataclasses.replace(c.oracle, budget="env_steps")
        states = []
        parts = []
        for i in range(c.fcp.agents):
            oracle = Oracle(c.env, oracle_config, Seating(), fcp_seed(c.seed, i))
            try:
                states.append(oracle.weights([LEARNER])[LEARNER])
                half = c.fcp.env_steps // 2
                for part, budget in (("middle", half), ("end", c.fcp.env_steps - half)):
                    stats = oracle.train(
                        budget,
                        desc=f"pre-train (FCP agent {i}, to {part})",
                        progress=ctx.progress,
                    )
                    parts.append(stats)
                    states.append(oracle.weights([LEARNER])[LEARNER])
            finally:
                oracle.stop()
        total = summed(parts)
        said = f"trained {c.fcp.agents} self-play agent(s) for FCP ({len(states)} checkpoints)"
        return Built(states, total, said)


def fcp_seed(run_seed: int, agent: int) -> int:
    """The seed of FCP's self-play agent `agent`: apart from the run's own and each other's."""
    return run_seed + 1000 * (agent + 1)


METHOD = FCP("fcp", "FCP: a best response to frozen self-play checkpoints, drawn uniformly")
