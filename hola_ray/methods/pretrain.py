"""Generation 0's builders: MEP's pre-training of the initial members (`pretrain_population`,
which PBT's trained starts use too), judged as teams of their own copies and stopped once
every member is competent, and a shipped population taken as it is (`shipped_members`)."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from hola_ray.config.oracle import Seating
from hola_ray.population.evaluators import evaluate_teams

if TYPE_CHECKING:
    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.context import Context
    from hola_ray.methods.generation_zero import GenerationZero
    from hola_ray.oracle.stats import TrainStats
    from hola_ray.oracle.trainer import Oracle


@dataclass(frozen=True)
class Built:
    """A method's generation 0: the initial members' RLlib states, what building them
    cost, and one line that says how they were built."""

    states: list[dict[str, Any]]
    stats: TrainStats
    said: str
    metrics: dict[str, float] = field(default_factory=dict)
    """what generation 0's metrics row adds (`pretrain_*`: how pre-training stopped)"""


JUDGE_SEED = 7_000_003
"""the run seed of the episodes pre-training's members are judged on"""


def shipped_members(zero: GenerationZero) -> Built:
    """The members of a shipped population built in another scenario (`zero.differ`: the
    fields, as dotted names), taken as a run's generation 0; the run weighs its G_0 itself."""
    from hola_ray.oracle.stats import TrainStats
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


def pretrain_population(ctx: Context, alpha: float, how: str, scheme: str) -> Built:
    """`population.initial_size` members trained together with MEP's population-entropy
    bonus of weight `alpha` (0: none), each in self-play (`scheme` "self-play": one member
    in every seat of an episode) or drawn per seat into mixed teams ("mixed"), for
    `pretrain.env_steps`; with `pretrain.until_success`, judged every `check_every` env
    steps as teams of their own copies and stopped once every member is competent. After
    each check the members are saved in the run directory (`RunDir.save_pretrain`): a
    stopped build resumes from its last check, with a fresh optimizer and sampler and its
    learning rate's schedule (`oracle.lr_decay_env_steps`) as far on as the check."""
    build = _Pretraining(ctx, alpha, scheme)
    try:  # a build stopped after its deciding check (while judging G_0) trains no more
        build.train()
        states = build.mep.weights(build.mep.members)
    finally:
        build.mep.stop()
    n = ctx.config.population.initial_size
    said = f"pre-trained {n} members {how} ({scheme}; {build.stop_reason()})"
    return Built([states[m] for m in build.mep.members], build.stats(), said, build.metrics())


class _Pretraining:
    """One pre-training build in progress: its Oracle of members, the env steps done
    (`resumed` of them before a stop), its checks and the time spent judging them."""

    def __init__(self, ctx: Context, alpha: float, scheme: str) -> None:
        self.ctx, self.alpha, self.scheme = ctx, alpha, scheme
        self.p = p = ctx.config.pretrain
        self.parts: list[TrainStats] = []
        self.extra: dict[str, float] = {}
        self.done, self.judge_s = 0, 0.0
        self.checks: list[dict[str, Any]] = []  # every check's figures, saved with the members
        saved = ctx.run.load_pretrain() if p.until else None
        if saved is not None:  # a stopped build: on from its last check (a fresh optimizer)
            states, progress = saved
            self.done, self.judge_s = int(progress["env_steps"]), float(progress["judge_s"])
            self.checks = list(progress.get("checks", []))
        start = self.members_from() if saved is None and p.members_from != "none" else None
        self.mep = self.oracle(0.0 if self.bonus_ends(self.done) else alpha)
        if start is not None:
            self.mep.set_trained_weights(dict(zip(self.mep.members, start, strict=True)))
        if saved is not None:
            self.mep.set_trained_weights(states)
            self.mep.start_schedules_at(self.done)  # a decaying lr goes on from the check
            self.extra["pretrain_resumed_at"] = self.done
            ctx.say(f"pre-train: resumed after {self.done:,} env steps ({ctx.run.pretrain})")
        self.resumed = self.done
        self.in_a_row = self.passing() if p.until else 0

    def members_from(self) -> list[dict[str, Any]]:
        """`pretrain.members_from`'s members' RLlib states, node by node: the starting
        weights of this build's, node k's as member k's, verified as a shipped population
        is (files, observation layout, apart from the pools) before anything starts."""
        from hola_ray.population import shipped

        c = self.ctx.config
        folder = shipped.population_dir(c.pretrain.members_from, c.seed)
        donor, manifest = shipped.load(
            folder, c.seed, c.layout(), str(shipped.read(folder)["kind"])
        )
        nodes = sorted(int(e["node"]) for e in manifest["members"].values())
        if len(nodes) != c.population.initial_size:
            raise shipped.PopulationError(
                f"pretrain.members_from {donor.root.name} holds {len(nodes)} members; "
                f"this build trains {c.population.initial_size} (population.initial_size)"
            )
        self.extra["pretrain_members_from_env_steps"] = float(
            manifest.get("built", {}).get("pretrain_env_steps", float("nan"))
        )
        self.ctx.say(
            f"pre-train: the members start from {donor.root.name}'s nodes "
            f"{', '.join(map(str, nodes))} (built at commit {str(manifest.get('commit'))[:8]})"
        )
        return [donor.load_member_state(v) for v in nodes]

    def oracle(self, weight: float) -> Oracle:
        from hola_ray.oracle.trainer import Oracle

        c = self.ctx.config
        seating = Seating(
            mep_members=c.population.initial_size,
            mep_alpha=weight,
            mep_self_play=self.scheme == "self-play",
        )
        return Oracle(c.env, c.oracle, seating, c.seed)

    def bonus_ends(self, done: int) -> bool:
        """`pretrain.alpha_until`: α 0 from `done` env steps on."""
        return self.alpha > 0 and 0 < self.p.alpha_until <= done

    def passing(self) -> int:
        return passing_in_a_row(self.checks, self.p.until_success, self.p.until_collision)

    def competent(self) -> bool:
        return bool(self.p.until) and self.in_a_row >= self.p.until_in_a_row

    def train(self) -> None:
        """Train until the budget is spent or every member passed enough checks in a row."""
        p = self.p
        while self.done < p.env_steps and not self.competent():
            if self.bonus_ends(self.done) and self.mep.seating.mep_alpha > 0:
                self.drop_bonus()
            budget = p.env_steps - self.done
            if p.until:
                budget = min(p.check_every, budget)
            if self.bonus_ends(p.alpha_until) and self.done < p.alpha_until:
                budget = min(budget, p.alpha_until - self.done)
            stats = self.mep.train(budget, desc="pre-train (MEP)", progress=self.ctx.progress)
            self.parts.append(stats)
            self.done += stats.env_steps
            if p.until:
                self.check()

    def drop_bonus(self) -> None:
        """Go on with the same members and α 0 (a new Oracle: the bonus is in its loss)."""
        states = self.mep.weights(self.mep.members)
        self.mep.stop()
        self.mep = self.oracle(0.0)
        self.mep.set_trained_weights(states)
        self.mep.start_schedules_at(self.done)
        self.ctx.say(f"pre-train: α 0 from {self.done:,} env steps on (pretrain.alpha_until)")

    def check(self) -> None:
        """Judge the members as teams of their own copies and save them with every check."""
        start = time.perf_counter()
        figures = members_as_copies(self.ctx.config, self.mep)
        self.judge_s += time.perf_counter() - start
        self.checks.append(
            {
                "env_steps": self.done,
                "success": [round(f["success"], 4) for f in figures],
                "collision": [round(f["collision"], 4) for f in figures],
            }
        )
        self.ctx.say(
            f"pre-train: {self.done:,} env steps; members as copies: success "
            + ", ".join(f"{f['success']:.0%}" for f in figures)
            + ", collision "
            + ", ".join(f"{f['collision']:.0%}" for f in figures)
        )
        self.in_a_row = self.passing()
        if 0 < self.in_a_row < self.p.until_in_a_row:
            self.ctx.say(f"pre-train: every member competent, {self.in_a_row} check(s) in a row")
        # a stopped build resumes here (a check's worth at most lost); the last save holds
        # every check, the deciding one included, for the manifest
        self.ctx.run.save_pretrain(
            self.mep.weights(self.mep.members),
            {
                "members": self.mep.members,
                "env_steps": self.done,
                "judge_s": self.judge_s,
                "checks": self.checks,
            },
        )

    def stop_reason(self) -> str:
        if self.competent():
            reason = f"competent after {self.done:,} env steps"
            if self.p.until_in_a_row > 1:
                reason += f" ({self.in_a_row} checks in a row)"
            return reason
        return f"{self.p.env_steps:,} env steps" + (", not all competent" if self.p.until else "")

    def metrics(self) -> dict[str, float]:
        """What generation 0's metrics row adds: the last check's figures (judged here or
        before a stop) and how the build stopped."""
        out = dict(self.extra)
        if self.checks:
            out |= {
                "pretrain_members_success_min": min(self.checks[-1]["success"]),
                "pretrain_members_collision_max": max(self.checks[-1]["collision"]),
            }
        if self.p.until:
            out |= {
                "pretrain_competent": float(self.competent()),
                "pretrain_judge_s": round(self.judge_s, 2),
            }
        return out

    def stats(self) -> TrainStats:
        """What building cost, the env steps before a resume included."""
        if self.parts:
            stats = summed(self.parts)
        else:  # resumed after its deciding check: nothing trained in this process
            from hola_ray.oracle.stats import TrainStats

            stats = TrainStats.untrained()
        if self.resumed:
            stats = dataclasses.replace(stats, env_steps=stats.env_steps + self.resumed)
        return stats


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
    env = config.env.judged()  # a team that changes: the contract's 3-pursuer bar (§5.1)
    teams = [(k,) * env.n_pursuers for k in exports]
    judged = evaluate_teams(
        env,
        teams,
        exports,
        config.pretrain.until_episodes,
        [JUDGE_SEED] * len(teams),
    )
    return [{"success": r.success, "collision": r.collision} for r in judged]


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
