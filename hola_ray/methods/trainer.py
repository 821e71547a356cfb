"""The one trainer (SPEC §5): generations of Oracle → judge → coordinator.

Every method (`hola_ray.methods.registry.METHODS`) runs this loop; it asks the method
(`hola_ray.methods.base.Method`) where methods differ and has no branch on a method's name.
Generation 0 builds the partner population (`Method.build_population`) and G_0; then each
generation the Oracle trains the learner with partners as the coordinator's plan says (one
call: slot → member and φ, drawn by the method's `Rules`), the Grapher weighs the
learner's hyperedges and the coordinator accepts it into the population or not, as the
method's `Rules` decide. A self-play method has no population: the Oracle seats the learner
in every slot and the learner is judged by its own team's rollout. The driver only
sequences the phases; the population lives in the coordinator actor, the hyperedge
evaluations and the monitors in evaluation actors, the PPO in RLlib's env runners and
learner. Every method leaves `learner.pt` (the latest learner) and `best.pt` with
`best.json` (the generation whose learner did best with the validation teammates, or in
its own judging without them)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import ray
from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

from hola_ray import interrupt
from hola_ray.clock import PhaseClock
from hola_ray.evaluation.metrics import TEAM
from hola_ray.methods.config import RunConfig
from hola_ray.methods.monitors import Monitoring, validation_teammates
from hola_ray.oracle import LEARNER, Oracle
from hola_ray.population import shipped
from hola_ray.population.coordinator import Coordinator, coordinator_name, run_id
from hola_ray.population.evaluators import EvaluatorPool
from hola_ray.population.grapher import evaluate_edges, evaluate_edges_here
from hola_ray.population.lock import RunLock
from hola_ray.population.rundir import RunDir
from hola_ray.population.state import EdgeResult, edge_seed
from hola_ray.process import NAMESPACE

_REPORTED = tuple((m.name, m.field) for m in TEAM)
"""(metric name in metrics.csv, its field in an edge result or a rollout summary)"""


class RunError(RuntimeError):
    """A run cannot start or continue as asked (e.g. a run directory already in use)."""


@dataclass
class Trainer:
    """Runs one training run (any method) in `run_dir` on the connected Ray cluster."""

    config: RunConfig
    run_dir: Path
    progress: bool = True
    lock: RunLock | None = None
    """the run directory's lock, when the caller took it already (else `fit` takes it)"""
    saved: Callable[[int], Any] | None = None
    """called with g once generation g (and the files at the top) is on disk; and after a
    resume has written those files again (the experiment mirrors a trial's folder with it)"""
    adopt_from: tuple[Path, ...] = ()
    """run directories whose generation 0 a fresh run takes instead of pre-training, when
    one of them built it with the same `generation_zero_key` (an experiment's methods of
    one seed that share MEP's population: the same G_0, trained once)"""
    started: float | None = None
    """when the command began (`time.perf_counter()`): the first row this process writes
    counts its start from there (`hola_ray.clock`); None: from `fit`"""

    def __post_init__(self) -> None:
        self.run = RunDir(self.run_dir)
        self.name = run_id(str(self.run.root))
        c = self.config
        self.pool = EvaluatorPool(c.env.to_dict(), c.grapher.workers, run_name=self.name)
        self.monitoring = Monitoring(c, self.pool if c.grapher.workers else None)
        self.clock = PhaseClock(self.started)
        """the time of the metrics row in progress, by phase"""
        self.start_node = -1  # the member the learner started from (learner_start: member)
        self.foreign_population: tuple | None = None
        """a shipped population built in another scenario, whose G_0 this run weighs:
        (its folder, manifest, what to say, the fields that differ)"""

    # ---- entry --------------------------------------------------------------------------
    def fit(self) -> list[dict[str, Any]]:
        """Train until `config.generations`; returns the metrics rows written this call.
        Raises `RunDirLocked` before writing anything when another run holds the folder."""
        if self.started is None:
            self.clock = PhaseClock()
        lock = self.lock or RunLock(self.run_dir)
        owned = not lock.held
        note = lock.acquire()
        if note:
            self._say(note)
        try:
            return self._fit()
        finally:
            if owned:
                lock.release()

    def _fit(self) -> list[dict[str, Any]]:
        c, method = self.config, self.config.strategy
        clock = self.clock
        if self.started is not None:  # the command's imports and Ray's start
            clock.add("process", time.perf_counter() - clock.since)
        self.run.create(c.to_yaml())
        with clock.phase("population"):
            self._adopt()
        here = ray.get_runtime_context().get_node_id()
        self.coord = Coordinator.options(
            name=coordinator_name(str(self.run_dir)),
            namespace=NAMESPACE,
            scheduling_strategy=NodeAffinitySchedulingStrategy(node_id=here, soft=False),
        ).remote(
            str(self.run.root.resolve()),
            method.rules(c),
            c.population,
            c.l,
            c.seed,
            c.grapher.edges_per_learner,
            c.method,
        )
        with clock.phase("actors"):
            self.pool.start()  # they start while this driver goes on
        written: list[int] = []
        oracle = None
        if c.validation.enabled:
            with clock.phase("population"):
                validation_teammates(c)  # a missing or refused validation set fails at once
        try:
            # read here, not asked of the coordinator: its actor starts (seconds of imports)
            # while this driver pre-trains or builds its Oracle
            last = self.run.last_completed()
            if last is None and self.foreign_population is not None and c.generations:
                # generation 0 trains nothing (a shipped population weighed again): the
                # Oracle is built while the coordinator and evaluation actors start
                with clock.phase("oracle_build"):
                    oracle = make_oracle(c)
            if last is None and method.self_play:
                last = 0  # no population to pre-train: generation 1 is the first
            elif last is None:
                self._pretrain()
                written.append(last := 0)
                self._saved(0)
            else:
                self._say(f"resuming after generation {last} in {self.run.root}")
                if not self.run.monitored(last):  # stopped before its monitors were written
                    self._submit_monitors(last, self.run.load_learner_export(last))
                    self._complete()
                with clock.phase("commit"):
                    self._catch_up(last)
                self._saved(last)
            if last < self.config.generations:
                if oracle is None:
                    with clock.phase("oracle_build"):
                        oracle = make_oracle(c)
                with clock.phase("seat"):
                    learner = self.run.load_learner_state(last)
                    if learner is None and last == 0 and self._starts_from_member():
                        learner = self._starting_member()
                    if learner is not None:
                        oracle.set_trained_weights({LEARNER: learner})
                    training = self.run.load_training_state(last) if last >= 1 else None
                    if training is not None:  # Adam's moments and the schedules go on
                        oracle.set_training_state(training)
                for g in range(last + 1, self.config.generations + 1):
                    self._generation(g, oracle)
                    written.append(g)
                    self._saved(g)
            if oracle is not None:  # its processes go while the last monitors play
                oracle.stop()
                oracle = None
            if self._complete():  # the last generation's monitors
                self._saved(written[-1])
        finally:
            if oracle is not None:
                oracle.stop()
            self.pool.shutdown()
            ray.get(self.coord.close.remote())
            ray.kill(self.coord)
        return [self.run.metrics(g) for g in written]

    # ---- generation 0 -------------------------------------------------------------------
    def _adopt(self) -> None:
        """A fresh run whose generation 0 another run already built (`adopt_from`, the same
        `generation_zero_key`) takes it instead of pre-training again."""
        c = self.config
        if self.run.last_completed() is not None:
            return
        if c.pretrain.shipped and c.strategy.population_kind is not None:
            self._adopt_shipped()
            return
        key = c.generation_zero_key()
        if key is None:
            return
        for folder in self.adopt_from:
            donor = RunDir(folder)
            marker = donor.generation(0) / KEY_FILE
            if Path(folder).resolve() == self.run.root.resolve() or not marker.is_file():
                continue
            if marker.read_text() != key:
                continue
            self.run.adopt_generation_zero(donor)
            self._say(f"gen 0: adopted from {donor.root.name} (the same pre-training and G_0)")
            return

    def _adopt_shipped(self) -> None:
        """Generation 0 is a shipped population (`pretrain.population`), verified, fitting
        the run's layout and apart from every pool (`hola_ray.population.shipped`). Built in
        this run's scenario (reward included), its generation 0 is copied in whole; built
        in another (say SPEC's approach term, where the run has own_move), its members are
        taken and G_0 is weighed again under the run's own (`_pretrain`): a hyperedge's
        weight is a team return, and η compares the learner's hyperedges with G_0's."""
        c = self.config
        kind, size = c.strategy.population_kind, c.strategy.population_size(c)
        kinds = (kind, *c.strategy.also_seats)
        donor, manifest = shipped.load(c.pretrain.population, c.seed, c.layout(), kinds)
        if len(manifest["members"]) != size:
            raise shipped.PopulationError(
                f"population {donor.root.name} holds {len(manifest['members'])} members; "
                f"method {c.method} with this config builds {size}"
            )
        built_in = RunConfig.from_dict(manifest["config_values"]).env
        said = (
            f"the shipped population {donor.root.name} ({size} members, built at commit "
            f"{str(manifest.get('commit'))[:8]}, seed {manifest.get('seed')})"
        )
        if built_in != c.env:
            self.foreign_population = (donor, manifest, said, _differences(built_in, c.env))
            return
        self.run.adopt_generation_zero(donor)
        self._say(f"gen 0: {said}")

    def _starts_from_member(self) -> bool:
        c = self.config
        has_members = c.strategy.population_kind is not None or c.pretrain.shipped
        own = c.strategy.sets_learner  # PBT: each generation starts from one of its agents
        return c.pretrain.learner_start == "member" and has_members and not own

    def _starting_member(self) -> dict[str, Any]:
        """`pretrain.learner_start: member`: the RLlib state of generation 0's member with
        the highest η (the lowest node on a tie), which the learner starts from; for a
        method without a population (self-play), the shipped population's (`_shipped_start`)."""
        if self.config.strategy.population_kind is None:
            return self._shipped_start()
        members = ray.get(self.coord.view.remote())["members"]
        node = shipped.most_preferred({m["node"]: m["eta"] for m in members})
        best = next(m for m in members if m["node"] == node)
        self._say(
            f"gen 1: the learner starts from member {best['node']} (η {best['eta'] or 0:.3f}, "
            f"the highest of {len(members)})"
        )
        self.start_node = best["node"]
        return ray.get(self.coord.member_states.remote([best["node"]]))[best["node"]]

    def _shipped_start(self) -> dict[str, Any]:
        """Self-play's learner from the most preferred member of the shipped population
        `pretrain.population` names (say FCP's, whose members are self-play checkpoints):
        the strategy a population method's learner starts from, without the population."""
        c = self.config
        donor, manifest, node, eta = shipped.preferred_member(
            c.pretrain.population, c.seed, c.layout()
        )
        self._say(
            f"gen 1: the learner starts from member {node} of the shipped population "
            f"{donor.root.name} (η {eta:.3f}, the highest of {len(manifest['members'])})"
        )
        self.start_node = node
        return donor.load_member_state(node)

    def _pretrain(self) -> dict[str, Any]:
        c, clock = self.config, self.clock
        self.coord.set_phase.remote("pretrain")
        start = time.perf_counter()
        # a shipped population's members (weighed again here), or pre-training
        with clock.phase("population" if self.foreign_population else "pretrain"):
            built = c.strategy.generation_zero(self)
            states_list, stats = built.states, built.stats
            exports = [c.export(s) for s in states_list]
        pretrain_s = time.perf_counter() - start
        with clock.phase("coordinator"):
            ray.get(self.coord.init_population.remote(exports, states_list))

        self.coord.set_phase.remote("grapher")
        results, grapher = self._grapher(0)
        self.coord.set_phase.remote("coordinator")
        with clock.phase("coordinator"):
            ray.get(self.coord.record.remote(results))
        metrics = {
            "env_steps": 0,
            "monitored": 0,
            "pretrain_env_steps": stats.env_steps,
            "pretrain_s": round(pretrain_s, 2),
            "pretrain_env_steps_per_s": round(stats.env_steps_per_s, 1),
            **{f"pretrain_{k}": round(v, 4) for k, v in stats.spread.items()},
            **built.metrics,
            **_edge_summary("population", results),
            **grapher,
            **clock.close(),
        }
        with clock.phase("commit"):  # in the next row's account
            row = ray.get(self.coord.commit.remote(0, metrics, None, None, stats.iteration_log))
            key = c.generation_zero_key()
            if key is not None:  # what another run of the same pre-training may adopt
                (self.run.generation(0) / KEY_FILE).write_text(key)
        self._submit_monitors(0, None)
        self._say(
            f"gen 0: {built.said} in {pretrain_s:.0f}s; "
            f"G_0 success {row['population_success']:.0%}, "
            f"return {row['population_return']:.1f}"
        )

    # ---- generations 1.. ----------------------------------------------------------------
    def _generation(self, g: int, oracle: Oracle) -> None:
        c, method, clock = self.config, self.config.strategy, self.clock
        prev = ray.get(self.coord.view.remote())["last_metrics"]
        self.coord.set_phase.remote("oracle")
        start = time.perf_counter()
        with clock.phase("seat"):
            slot = method.before_training(self, g, oracle)
            if not method.self_play:
                oracle.seat(
                    ray.get(self.coord.plan.remote(slot)),
                    lambda nodes: ray.get(self.coord.member_states.remote(nodes)),
                    salt=g,
                )
            oracle.reseed(g)  # generation g samples alike, resumed or not
        trained = time.perf_counter()
        stats = oracle.train(c.oracle.env_steps, desc=f"gen {g} oracle", progress=self.progress)
        trained = time.perf_counter() - trained
        clock.add("oracle_update", stats.learn_s)
        clock.add("oracle_sample", trained - stats.learn_s)
        with clock.phase("export"):
            learner_state = oracle.weights([LEARNER])[LEARNER]
            training = oracle.training_state()
            export = oracle.export_state(learner_state)
        oracle_s = time.perf_counter() - start
        self._complete()  # the previous generation's monitors, played while this one trained

        if method.self_play:
            judged, decision = {}, None
        else:
            judged, decision = self._judge_in_population(g, export, learner_state, slot)
        metrics = {
            "monitored": 0,
            "env_steps": int(prev.get("env_steps", 0)) + stats.env_steps,
            "learner_samples": int(prev.get("learner_samples", 0)) + stats.learner_samples,
            "gradient_steps": int(prev.get("gradient_steps", 0)) + stats.gradient_steps,
            "oracle_s": round(oracle_s, 2),
            "oracle_env_steps_per_s": round(stats.env_steps_per_s, 1),
            "oracle_sampled_steps_per_s": round(stats.sampled_steps_per_s, 1),
            "oracle_sample_s": round(stats.sample_s, 2),
            "oracle_learn_s": round(stats.learn_s, 2),
            "oracle_learner_return": stats.module_return.get(LEARNER, float("nan")),
            **({"learner_start_node": self.start_node} if g == 1 and self.start_node >= 0 else {}),
            **{k: round(v, 4) for k, v in stats.spread.items()},
            **judged,
            **clock.close(),
        }
        with clock.phase("commit"):  # in the next row's account
            row = ray.get(
                self.coord.commit.remote(
                    g, metrics, learner_state, decision, stats.iteration_log, export, training
                )
            )
            # learner.json, written last, says the generation is saved (best.pt follows
            # its monitors: `_complete`)
            self._save_learner(g, export, None if decision is None else decision.to_dict())
        self._submit_monitors(g, export)
        judged_as = (
            ""
            if method.self_play
            else f"learner success {row['learner_success']:.0%} ± "
            f"{row['learner_success_se']:.0%}, collision {row['learner_collision']:.0%}, "
            f"return {row['learner_return']:.1f}; {method.verdict(c, decision)}; "
        )
        self._say(
            f"gen {g}: {judged_as}std {row.get('std_median', 0):.2f}; "
            f"oracle {oracle_s:.0f}s ({stats.env_steps_per_s:.0f} steps/s)"
        )

    def _submit_monitors(self, g: int, export: dict[str, Any] | None) -> None:
        """Start generation g's monitors (`hola_ray.methods.monitors`) of its learner's
        export and of the population as the coordinator holds it now."""
        members = None
        if not self.config.strategy.self_play:
            nodes = sorted(ray.get(self.coord.slots.remote()))
            members = ray.get(self.coord.exports.remote(nodes))
        self.coord.set_phase.remote("monitors")
        self.monitoring.submit(g, export, members)

    def _complete(self) -> bool:
        """Write the pending generation's monitors beside it and keep its learner as best.pt
        if it did best (waiting for them: the phase `monitors`); False when none pend."""
        with self.clock.phase("monitors"):
            done = self.monitoring.collect()
            if done is None:
                return False
            g, figures = done
            ray.get(self.coord.complete.remote(g, figures))
            row = self.run.metrics(g)
            best = g >= 1 and self.run.keep_best(g, row, self.run.load_learner_export(g))
        judged = ""
        if "members_success" in figures:
            judged = (
                f"members as copies success {row['members_success']:.0%} (the weakest "
                f"{row['members_success_min']:.0%}), teams of members "
                f"{row['population_team_success']:.0%}; "
            )
        if "learner_success" in figures:  # self-play: the learner as copies
            judged = (
                f"as {self.config.env.n_pursuers} copies success {row['learner_success']:.0%}, "
                f"collision {row['learner_collision']:.0%}; "
            )
        if "val_success" in figures:
            judged += (
                f"with the validation teammates success {row['val_success']:.0%}, "
                f"collision {row['val_collision']:.0%}, own crash {row['val_learner_crash']:.0%}; "
            )
        kept = "best so far" if best else f"best stays generation {self.run.best_generation()}"
        self._say(f"gen {g} monitored: {judged}{kept if g >= 1 else ''}".rstrip("; "))
        return True

    def _save_learner(self, g: int, export: dict[str, Any], decision: dict | None) -> None:
        """learner.pt and learner.json: generation g's learner, and whether it joined."""
        accepted = decision is not None and bool(decision["accepted"])
        self.run.save_learner(export)
        self.run.save_learner_info(
            {
                "generation": g,
                "method": self.config.method,
                "in_population": None if decision is None else accepted,
                "node": decision["candidate"] if accepted else None,
                "population": "population/members.json" if decision is not None else None,
            }
        )

    def _catch_up(self, last: int) -> None:
        """A run killed after committing generation `last` but before writing the files
        at the top of its directory: best.pt and best.json from the best of the completed
        generations, then learner.pt and learner.json (the last written, so a learner.json
        of generation `last` says all of them are) from that generation's folder."""
        if last < 1 or not self.run.learner_state(last).is_file():
            return
        best = self.run.best_of_completed()
        if best is not None and (self.run.best_generation() != best or not self.run.best.is_file()):
            self.run.best_info.unlink(missing_ok=True)
            state = self.run.load_learner_state(best)
            self.run.keep_best(best, self.run.metrics(best), self.config.export(state))
            self._say(f"best.pt written again from generation {best}")
        if self.run.learner_generation() != last:
            state = self.run.load_learner_state(last)
            decision = self.run.read_json(last, "state.json")["decision"]
            self._save_learner(last, self.config.export(state), decision)
            self._say(f"learner.pt written again from generation {last}")

    def _judge_in_population(self, g: int, export, learner_state, slot: int | None = None):
        """The Grapher weighs the learner's hyperedges; the coordinator decides (pbt: on
        the agent of `slot`)."""
        self.coord.set_phase.remote("grapher")
        with self.clock.phase("grapher"):
            candidate = ray.get(self.coord.propose.remote(export, learner_state))
        results, grapher = self._grapher(g)
        self.coord.set_phase.remote("coordinator")
        with self.clock.phase("coordinator"):
            ray.get(self.coord.record.remote(results))
            decision = ray.get(self.coord.decide.remote(slot, g))
        judged = {
            **_edge_summary("learner", results),
            **grapher,
            "candidate": candidate,
            "accepted": int(decision.accepted),
            "rank": decision.rank,
            "eta": decision.eta,
            "replaced": -1 if decision.replaced is None else decision.replaced,
            "copied_from": -1 if decision.copied_from is None else decision.copied_from,
        }
        return judged, decision

    def _grapher(self, g: int) -> tuple[list[EdgeResult], dict[str, float]]:
        c = self.config
        with self.clock.phase("grapher"):
            edges = ray.get(self.coord.edges_to_evaluate.remote(g))
            nodes = sorted({v for e in edges for v in e})
            exports = ray.get(self.coord.exports.remote(nodes))

        def seed_of(edge: tuple[int, ...]) -> int:
            return edge_seed(c.seed, g, edge)

        if c.grapher.workers == 0:
            with self.clock.phase("grapher"):
                results, stats = evaluate_edges_here(
                    edges,
                    exports,
                    c.env.to_dict(),
                    c.grapher.episodes_per_edge,
                    seed_of,
                    parts=c.grapher.chunks,
                    desc=f"gen {g} grapher",
                    progress=self.progress,
                )
        else:
            with self.clock.phase("grapher"):
                results, stats = evaluate_edges(
                    edges,
                    self.pool,
                    ray.put(exports),
                    c.grapher.episodes_per_edge,
                    seed_of=seed_of,
                    parts=c.grapher.chunks,
                    desc=f"gen {g} grapher",
                    progress=self.progress,
                )
        return results, {
            "grapher_edges": stats.edges,
            "grapher_s": round(stats.wall_s, 2),
            "grapher_episodes_per_s": round(stats.episodes_per_s, 1),
            "grapher_retries": stats.retries,
        }

    def _saved(self, g: int) -> None:
        interrupt.check()
        if self.saved is not None:
            self.saved(g)

    def _say(self, text: str) -> None:
        print(text, flush=True)


def make_oracle(config: RunConfig, seed: int | None = None) -> Oracle:
    """The Oracle a run of `config` trains its learner with, seated as its method says."""
    seating = config.strategy.seating(config)
    return Oracle(config.env, config.oracle, seating, config.seed if seed is None else seed)


KEY_FILE = "generation_zero_key.json"
"""in a generation-0 folder: the `generation_zero_key` it was built with"""


def _differences(a: Any, b: Any, prefix: str = "env") -> str:
    """The fields in which two (nested) config dataclasses differ, as dotted names."""
    out = []
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if dataclasses.is_dataclass(x) and x != y:
            out.append(_differences(x, y, f"{prefix}.{f.name}"))
        elif x != y:
            out.append(f"{prefix}.{f.name}")
    return ", ".join(out)


def _edge_summary(prefix: str, results: list[EdgeResult]) -> dict[str, float]:
    """Episode-weighted means over hyperedges, with the standard error across hyperedges."""
    n = np.array([r.episodes for r in results], dtype=np.float64)
    out: dict[str, float] = {}
    for name, key in _REPORTED:
        x = np.array([getattr(r, key) for r in results], dtype=np.float64)
        mean = float((x * n).sum() / n.sum())
        se = float(x.std(ddof=1) / np.sqrt(x.size)) if x.size > 1 else 0.0
        out[f"{prefix}_{name}"] = round(mean, 4)
        out[f"{prefix}_{name}_se"] = round(se, 4)
    return out


def check_run_dir(run_dir: Path, resume: bool) -> None:
    """Refuse to start a fresh run over a run directory that has generations."""
    run = RunDir(run_dir)
    if resume:
        if not run.config.is_file():
            raise RunError(f"--resume {run_dir}: no config.yaml there, not a run directory")
    elif run.completed():
        raise RunError(
            f"{run_dir} already holds generations {run.completed()}; "
            f"continue it with --resume {run_dir} or pick another --out"
        )
