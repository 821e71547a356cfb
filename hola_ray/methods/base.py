"""What a training method is: a strategy over the one trainer (docs/contract.md §5).

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

from hola_ray.config.oracle import Seating
from hola_ray.methods.context import Context
from hola_ray.methods.pretrain import Built, pretrain_population, shipped_members
from hola_ray.population.rules import Uniform
from hola_ray.population.state import Decision

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig
    from hola_ray.oracle.trainer import Oracle


@dataclass(frozen=True)
class Origin:
    """Where a method's generation 0 comes from (`Method.origin`), which
    `generation_zero.resolve` reads before Ray starts."""

    kind: str | None = "mep"
    """what builds it (`build_population`); a shipped population of this kind may replace
    it (`pretrain.population`). None: the method has no population"""
    also: tuple[str, ...] = ()
    """other kinds of shipped population it may take as generation 0"""
    shared: bool = False
    """generation 0 is MEP's population, the same for every method that says so: one run
    may adopt another's (`RunConfig.generation_zero_key`)"""
    sets_learner: bool = False
    """each generation puts its own weights into the learner (`before_training`; PBT
    trains its agents in turn): `pretrain.learner_start` does not apply"""


class Method:
    """The protocol every method implements; the defaults are HOLA-Drone's shape: an MEP
    population, the learner in one seat beside partners, and a learner that may join."""

    name: str
    description: str
    origin: ClassVar[Origin] = Origin()
    """where its generation 0 comes from"""
    section: ClassVar[tuple[str, type] | None] = None
    """the method's own run-config section (name, frozen dataclass with `validate()`), or
    None; `config.<name>` reads it"""

    def __init__(self, name: str, description: str):
        self.name, self.description = name, description

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"

    # ---- what the method is -------------------------------------------------------------
    def trains_alone(self) -> bool:
        """The learner fills every seat (self-play): no population, no pre-training, no
        Grapher, no partners seated; it is judged by its own team's rollout."""
        return False

    def may_join(self) -> bool:
        """The learner may join the population (False: a best response to a fixed one)."""
        return True

    # ---- configuration ------------------------------------------------------------------
    def validate(self, config: RunConfig) -> None:
        """Checks that span sections (ConfigError naming the field)."""

    def seating(self, config: RunConfig) -> Seating:
        """How the Oracle seats the learner each generation."""
        if self.trains_alone():
            return Seating()
        return Seating(partners=config.population.max_size)

    def make_oracle(self, config: RunConfig, seed: int | None = None) -> Oracle:
        """The Oracle a run of `config` trains its learner with, seated as this method
        says (`seed`: the run's unless given)."""
        seed = config.seed if seed is None else seed
        from hola_ray.oracle.trainer import Oracle  # RLlib: not needed to read a config

        return Oracle(config.env, config.oracle, self.seating(config), seed)

    def population_size(self, config: RunConfig) -> int:
        """How many members `build_population` builds."""
        return config.population.initial_size

    def rules(self, config: RunConfig) -> Any:
        """The coordinator's `Rules` for this run (`hola_ray.population.rules`)."""
        return Uniform(admit=self.may_join())

    def rival(self, config: RunConfig) -> Any:
        """`Rules` whose φ each generation's φ is compared with, on the same hypergraph
        (the row's `phi_tv`: their total variation distance), or None."""
        return None

    # ---- the generation loop ------------------------------------------------------------
    def build_population(self, ctx: Context) -> Built:
        """Generation 0: the initial members (default: MEP pre-training)."""
        c = ctx.config
        return pretrain_population(ctx, c.pretrain.alpha, "with MEP", c.pretrain.scheme)

    def generation_zero(self, ctx: Context) -> Built:
        """What the trainer calls for generation 0: the members of a shipped population
        built in another scenario (`shipped_members`), else `build_population`."""
        if ctx.zero.source == "reweigh":
            return shipped_members(ctx.zero)
        return self.build_population(ctx)

    def before_training(self, ctx: Context, g: int, oracle: Oracle) -> int | None:
        """Called before generation g's Oracle trains; returns the population slot of the
        member the learner was seated from (PBT), else None."""
        return None

    def member_roles(self, nodes: list[int]) -> dict[int, str]:
        """Each generation-0 member's role in a shipped population's manifest."""
        return dict.fromkeys(nodes, "member")

    def verdict(self, config: RunConfig, decision: Decision) -> str:
        """What the generation's log line says about the coordinator's decision."""
        if decision.accepted:
            return f"accepted as node {decision.candidate} (rank {decision.rank}" + (
                f", replaces {decision.replaced})" if decision.replaced is not None else ")"
            )
        if not self.may_join():
            return f"population fixed ({self.name}: a best response; η rank {decision.rank})"
        if decision.rank <= config.population.top_m:  # within the top m, yet nobody prefers it
            return f"rejected (η 0: no member prefers it; rank {decision.rank})"
        return f"rejected (rank {decision.rank} > top {config.population.top_m})"
