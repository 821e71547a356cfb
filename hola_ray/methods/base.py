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

import dataclasses
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

from hola_ray.oracle.config import Seating
from hola_ray.population.evaluators import evaluate_teams
from hola_ray.population.rules import Uniform
from hola_ray.population.state import Decision

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.generation_zero import GenerationZero
    from hola_ray.methods.trainer import Trainer
    from hola_ray.oracle.trainer import Oracle, TrainStats


@dataclass(frozen=True)
class Built:
    """A method's generation 0: the initial members' RLlib states, what building them
    cost, and one line that says how they were built."""

    states: list[dict[str, Any]]
    stats: TrainStats
    said: str
    metrics: dict[str, float] = field(default_factory=dict)
    """what generation 0's metrics row adds (`pretrain_*`: how pre-training stopped)"""


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
    self_play: ClassVar[bool] = False
    """the learner in every seat: no population, no pre-training, no Grapher; the learner
    is judged by its own team's rollout"""
    joins: ClassVar[bool] = True
    """the learner may join the population (False: a best response to a fixed one)"""
    origin: ClassVar[Origin] = Origin()
    """where its generation 0 comes from"""
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
        return Uniform(admit=self.joins)

    def rival(self, config: RunConfig) -> Any:
        """`Rules` whose φ each generation's φ is compared with, on the same hypergraph
        (the row's `phi_tv`: their total variation distance), or None."""
        return None

    # ---- the generation loop ------------------------------------------------------------
    def build_population(self, trainer: Trainer) -> Built:
        """Generation 0: the initial members (default: MEP pre-training)."""
        c = trainer.config
        return pretrain_population(trainer, c.pretrain.alpha, "with MEP", c.pretrain.scheme)

    def generation_zero(self, trainer: Trainer) -> Built:
        """What the trainer calls for generation 0: the members of a shipped population
        built in another scenario (`shipped_members`), else `build_population`."""
        if trainer.zero.source == "reweigh":
            return shipped_members(trainer.zero)
        return self.build_population(trainer)

    def before_training(self, trainer: Trainer, g: int, oracle: Oracle) -> int | None:
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
        if not self.joins:
            return f"population fixed ({self.name}: a best response; η rank {decision.rank})"
        return f"rejected (rank {decision.rank} > top {config.population.top_m})"


def shipped_members(zero: GenerationZero) -> Built:
    """The members of a shipped population built in another scenario (`zero.differ`: the
    fields, as dotted names), taken as a run's generation 0; the run weighs its G_0 itself."""
    from hola_ray.oracle.trainer import TrainStats
    from hola_ray.population.rundir import RunDir

    donor, manifest, said, differ = RunDir(zero.donor), zero.manifest, zero.said, zero.differ
    nodes = sorted(e["node"] for e in manifest["members"].values())
    stats = TrainStats(0, 0, 0.0, 0.0, 0.0, float("nan"), {})
    note = f"{said}; G_0 weighed under this run's scenario ({differ} differ)"
    metrics = {"adopted_from": donor.root.name}
    built = manifest.get("built", {})
    if "pretrain_env_steps" in built:
        metrics["adopted_pretrain_env_steps"] = built["pretrain_env_steps"]
    return Built([donor.load_member_state(v) for v in nodes], stats, note, metrics)


def pretrain_population(trainer: Trainer, alpha: float, how: str, scheme: str) -> Built:
    """`population.initial_size` members trained together with MEP's population-entropy
    bonus of weight `alpha` (0: none), each in self-play (`scheme` "self-play": one member
    in every seat of an episode) or drawn per seat into mixed teams ("mixed"), for
    `pretrain.env_steps`; with `pretrain.until_success`, judged every `check_every` env
    steps as teams of their own copies and stopped once every member is competent. After
    each check the members are saved in the run directory (`RunDir.save_pretrain`): a
    stopped build resumes from its last check, with a fresh optimizer and sampler and its
    learning rate's schedule (`oracle.lr_decay_env_steps`) as far on as the check."""
    from hola_ray.oracle.trainer import Oracle

    c = trainer.config
    p, n = c.pretrain, c.population.initial_size

    def oracle(weight: float) -> Oracle:
        mode = scheme == "self-play"
        seating = Seating(mep_members=n, mep_alpha=weight, mep_self_play=mode)
        return Oracle(c.env, c.oracle, seating, c.seed)

    def bonus_ends(done: int) -> bool:  # `alpha_until`: α 0 from here on
        return alpha > 0 and 0 < p.alpha_until <= done

    parts: list[TrainStats] = []
    metrics: dict[str, float] = {}
    done, judge_s, stop = 0, 0.0, ""
    checks: list[dict[str, Any]] = []  # every check's figures, kept with the saved members
    saved = trainer.run.load_pretrain() if p.until else None
    if saved is not None:  # a stopped build: on from its last check (a fresh optimizer)
        states, progress = saved
        done, judge_s = int(progress["env_steps"]), float(progress["judge_s"])
        checks = list(progress.get("checks", []))
    mep = oracle(0.0 if bonus_ends(done) else alpha)
    if saved is not None:
        mep.set_trained_weights(states)
        mep.start_schedules_at(done)  # a decaying lr goes on from the check
        metrics["pretrain_resumed_at"] = done
        trainer.say(f"pre-train: resumed after {done:,} env steps ({trainer.run.pretrain})")
    resumed = done
    in_a_row = passing_in_a_row(checks, p.until_success, p.until_collision) if p.until else 0
    try:  # a build stopped after its deciding check (while judging G_0) trains no more
        while done < p.env_steps and not (p.until and in_a_row >= p.until_in_a_row):
            if bonus_ends(done) and mep.seating.mep_alpha > 0:
                states = mep.weights(mep.members)
                mep.stop()
                mep = oracle(0.0)
                mep.set_trained_weights(states)
                mep.start_schedules_at(done)
                trainer.say(f"pre-train: α 0 from {done:,} env steps on (pretrain.alpha_until)")
            budget = min(p.check_every, p.env_steps - done) if p.until else p.env_steps - done
            if bonus_ends(p.alpha_until) and done < p.alpha_until:
                budget = min(budget, p.alpha_until - done)
            parts.append(mep.train(budget, desc="pre-train (MEP)", progress=trainer.progress))
            done += parts[-1].env_steps
            if not p.until:
                continue
            start = time.perf_counter()
            figures = members_as_copies(c, mep)
            judge_s += time.perf_counter() - start
            checks.append(
                {
                    "env_steps": done,
                    "success": [round(f["success"], 4) for f in figures],
                    "collision": [round(f["collision"], 4) for f in figures],
                }
            )
            trainer.say(
                f"pre-train: {done:,} env steps; members as copies: success "
                + ", ".join(f"{f['success']:.0%}" for f in figures)
                + ", collision "
                + ", ".join(f"{f['collision']:.0%}" for f in figures)
            )
            in_a_row = passing_in_a_row(checks, p.until_success, p.until_collision)
            if 0 < in_a_row < p.until_in_a_row:
                trainer.say(f"pre-train: every member competent, {in_a_row} check(s) in a row")
            # a stopped build resumes here (a check's worth at most lost); the last save
            # holds every check, the deciding one included, for the manifest
            trainer.run.save_pretrain(
                mep.weights(mep.members),
                {"members": mep.members, "env_steps": done, "judge_s": judge_s, "checks": checks},
            )
        if p.until and in_a_row >= p.until_in_a_row:
            stop = f"competent after {done:,} env steps"
            if p.until_in_a_row > 1:
                stop += f" ({in_a_row} checks in a row)"
        else:
            stop = f"{p.env_steps:,} env steps" + (", not all competent" if p.until else "")
        states = mep.weights(mep.members)
    finally:
        mep.stop()
    if checks:  # the last check's, whether judged in this process or before a stop
        metrics |= {
            "pretrain_members_success_min": min(checks[-1]["success"]),
            "pretrain_members_collision_max": max(checks[-1]["collision"]),
        }
    if p.until:
        metrics |= {
            "pretrain_competent": float(stop.startswith("competent")),
            "pretrain_judge_s": round(judge_s, 2),
        }
    said = f"pre-trained {n} members {how} ({scheme}; {stop})"
    if parts:
        stats = summed(parts)
    else:  # resumed after its deciding check: nothing trained in this process
        from hola_ray.oracle.trainer import TrainStats

        stats = TrainStats.untrained()
    if resumed:  # the env steps before the resume count too
        stats = dataclasses.replace(stats, env_steps=stats.env_steps + resumed)
    return Built([states[m] for m in mep.members], stats, said, metrics)


def passing_in_a_row(checks: list[dict[str, Any]], success: float, collision: float) -> int:
    """How many of the last checks in a row found every member competent (at least
    `success`, at most `collision`): a resumed build counts the checks before its stop."""
    count = 0
    for check in reversed(checks):
        ok = all(s >= success for s in check["success"]) and all(
            c <= collision for c in check["collision"]
        )
        if not ok:
            break
        count += 1
    return count


def members_as_copies(config: RunConfig, oracle: Oracle) -> list[dict[str, float]]:
    """Each of the Oracle's trained members as a team of its own copies, over
    `pretrain.until_episodes` episodes (the same episodes for every member and check):
    success and collision. Every member's episodes are one rollout (`evaluate_teams`)."""
    states = oracle.weights(oracle.members)
    exports = {k: oracle.export_state(states[m]) for k, m in enumerate(oracle.members)}
    teams = [(k,) * config.env.n_pursuers for k in exports]
    judged = evaluate_teams(
        config.env.to_dict(),
        teams,
        exports,
        config.pretrain.until_episodes,
        [JUDGE_SEED] * len(teams),
    )
    return [{"success": r.success, "collision": r.collision} for r in judged]


JUDGE_SEED = 7_000_003
"""the run seed of the episodes pre-training's members are judged on"""


def summed(parts: list[TrainStats]) -> TrainStats:
    """Several `Oracle.train` calls as one: counts and times summed, the last call's returns,
    every call's iterations in order."""
    if not parts:
        raise ValueError("no training to sum")
    sums = ("env_steps", "iterations", "wall_s", "sample_s", "learn_s")
    sums += ("learner_samples", "gradient_steps")
    return dataclasses.replace(
        parts[-1],
        **{k: sum(getattr(x, k) for x in parts) for k in sums},
        iteration_log=tuple(row for x in parts for row in x.iteration_log),
    )
