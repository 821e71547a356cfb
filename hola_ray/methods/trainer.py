"""The one trainer (docs/contract.md §5): generations of Oracle → judge → coordinator.

Every method (`hola_ray.methods.registry.METHODS`) runs this loop; it asks the method
(`hola_ray.methods.base.Method`) where methods differ and has no branch on a method's name.
Generation 0 builds the partner population and G_0; then each generation the Oracle trains
the learner with partners as the coordinator's plan says (slot → member and φ, drawn by the
method's `Rules`), the Grapher weighs the learner's hyperedges and the coordinator accepts
it or not. Self-play has no population: the learner sits in every slot and is judged by its
own team. The driver only sequences the phases: the population lives in the coordinator
actor, evaluations in evaluation actors, the PPO in RLlib. Every method leaves `learner.pt`
and `best.pt` with `best.json` (the generation judged best, `RunDir.keep_best`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import ray

from hola_ray import interrupt
from hola_ray.clock import PhaseClock
from hola_ray.methods import generation_zero
from hola_ray.methods.config import RunConfig
from hola_ray.methods.context import Context
from hola_ray.methods.generation_zero import KEY_FILE, GenerationZero
from hola_ray.methods.monitors import Monitoring, monitored, validation_teammates
from hola_ray.oracle import LEARNER, Oracle
from hola_ray.population.coordinator import (
    CoordinatorSettings,
    opened,
    run_id,
    start_coordinator,
)
from hola_ray.population.evaluators import EvaluatorPool
from hola_ray.population.files import TorchFile
from hola_ray.population.grapher import edge_summary, weigh
from hola_ray.population.lock import RunLock
from hola_ray.population.rundir import RunDir, phi_tie
from hola_ray.population.state import EdgeResult, edge_seed


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
    """run directories whose generation 0 (same `generation_zero_key`: an experiment's
    methods of one seed on MEP's population) a fresh run takes instead of pre-training"""
    started: float | None = None
    """when the command began (`time.perf_counter()`): the first row this process writes
    counts its start from there (`hola_ray.clock`); None: from `fit`"""
    zero: GenerationZero | None = None
    """where generation 0 comes from and where the learner starts, resolved before Ray
    started (`generation_zero.resolve`); None: resolved by `fit`"""
    tags: dict[str, str] | None = None
    """the run's metrics' tags, run and trial (`hola_ray.population.telemetry`)"""

    def __post_init__(self) -> None:
        self.run = RunDir(self.run_dir)
        self.name = run_id(str(self.run.root))
        c = self.config
        self.pool = EvaluatorPool(c.env, c.grapher.workers, run_name=self.name)
        self.monitoring = Monitoring(c, self.pool if c.grapher.workers else None)
        self.clock = PhaseClock(self.started)
        """the time of the metrics row in progress, by phase"""

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
            self.say(note)
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
        if self.zero is None:
            self.zero = generation_zero.resolve(c, self.run, self.adopt_from)
        zero = self.zero
        self.run.create(c.to_yaml())
        with clock.phase("population"):
            generation_zero.take(zero, self.run, self.say)
        self._start_coordinator()
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
            if last is None and zero.source == "reweigh" and c.generations:
                # generation 0 trains nothing (a shipped population weighed again): the
                # Oracle is built while the coordinator and evaluation actors start
                with clock.phase("oracle_build"):
                    oracle = method.make_oracle(c)
            if last is None and method.trains_alone():
                last = 0  # no population to pre-train: generation 1 is the first
            elif last is None:
                self._pretrain()
                written.append(last := 0)
                self._saved(0)
            else:
                self.say(f"resuming after generation {last} in {self.run.root}")
                if not self.run.monitored(last):  # stopped before its monitors were written
                    self._submit_monitors(last, self.run.load_learner_export(last))
                    self._complete()
                with clock.phase("commit"):
                    self._catch_up(last)
                self._saved(last)
            if last < self.config.generations:
                if oracle is None:
                    with clock.phase("oracle_build"):
                        oracle = method.make_oracle(c)
                with clock.phase("seat"):
                    started_from = self._seat_learner(oracle, last)
                for g in range(last + 1, self.config.generations + 1):
                    self._generation(g, oracle, started_from if g == 1 else None)
                    written.append(g)
                    self._saved(g)
            if oracle is not None:  # its processes go while the last monitors play
                oracle.stop()
                oracle = None
            if self._complete():  # the last generation's monitors
                self._saved(written[-1])
            rival = method.rival(c)
            if rival is not None and (said := phi_tie(self.run.metrics_rows(), rival.kind)):
                self.say(said)
        finally:
            if oracle is not None:
                oracle.stop()
            self.pool.shutdown()
            ray.get(self.coord.close.remote())
            ray.kill(self.coord)
        return [self.run.metrics(g) for g in written]

    def _start_coordinator(self) -> None:
        c, method = self.config, self.config.strategy
        settings = CoordinatorSettings(
            rules=method.rules(c),
            population=c.population,
            l=c.l,
            sizes=c.edge_sizes,
            seed=c.seed,
            edges_per_learner=c.grapher.edges_per_learner,
            initial_edges=c.grapher.initial_edges,
            method=c.method,
            rival=method.rival(c),
            tags=self.tags or {},
        )
        self.coord = start_coordinator(self.run.root, settings)

    def _seat_learner(self, oracle: Oracle, last: int) -> int | None:
        """The learner's weights after generation `last` (its start before generation 1:
        `pretrain.learner_start`), and its optimizer's and schedules' state where saved;
        returns the member it started from, if it started from one."""
        learner, started_from = self.run.load_learner_state(last), None
        if learner is None and last == 0:
            start = generation_zero.starting_member(self.zero, self.config, self.coord, self.say)
            if start is not None:
                started_from, learner = start
        if learner is not None:
            oracle.set_trained_weights({LEARNER: learner})
        training = self.run.load_training_state(last) if last >= 1 else None
        if training is not None:  # Adam's moments and the schedules go on
            oracle.set_training_state(training)
        return started_from

    # ---- generation 0 -------------------------------------------------------------------
    def _pretrain(self) -> dict[str, Any]:
        c, clock = self.config, self.clock
        self.coord.set_phase.remote("pretrain")
        start = time.perf_counter()
        # a shipped population's members (weighed again here), or pre-training
        with clock.phase("population" if self.zero.source == "reweigh" else "pretrain"):
            built = c.strategy.generation_zero(self.context())
            states_list, stats = built.states, built.stats
            exports = [c.export(s) for s in states_list]
        pretrain_s = time.perf_counter() - start
        with clock.phase("coordinator"):
            files = [TorchFile.of(x) for x in exports], [TorchFile.of(s) for s in states_list]
            ray.get(self.coord.init_population.remote(*files))

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
            **edge_summary("population", results),
            **grapher,
            **clock.close(),
        }
        with clock.phase("commit"):  # in the next row's account
            row = ray.get(self.coord.commit.remote(0, metrics, None, stats.iteration_log))
            key = c.generation_zero_key()
            if key is not None:  # what another run of the same pre-training may adopt
                (self.run.generation(0) / KEY_FILE).write_text(key)
        self._submit_monitors(0, None)
        self.say(
            f"gen 0: {built.said} in {pretrain_s:.0f}s; "
            f"G_0 success {row['population_success']:.0%}, "
            f"return {row['population_return']:.1f}"
        )

    # ---- generations 1.. ----------------------------------------------------------------
    def _generation(self, g: int, oracle: Oracle, started_from: int | None = None) -> None:
        """Train generation g (`started_from`: the member generation 1's learner started
        from, which its row names)."""
        c, method, clock = self.config, self.config.strategy, self.clock
        prev = ray.get(self.coord.view.remote())["last_metrics"]
        self.coord.set_phase.remote("oracle")
        start = time.perf_counter()
        with clock.phase("seat"):
            slot = method.before_training(self.context(), g, oracle)
            if not method.trains_alone():
                oracle.seat(
                    ray.get(self.coord.plan.remote(slot)),
                    self.member_states,
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

        if method.trains_alone():
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
            **({} if started_from is None else {"learner_start_node": started_from}),
            **{k: round(v, 4) for k, v in stats.spread.items()},
            **judged,
            **clock.close(),
        }
        with clock.phase("commit"):  # in the next row's account
            files = tuple(TorchFile.of(x) for x in (learner_state, export, training))
            row = ray.get(
                self.coord.commit.remote(g, metrics, decision, stats.iteration_log, files)
            )
            # learner.json, written last, says the generation is saved (best.pt follows
            # its monitors: `_complete`)
            self.run.save_latest(g, c.method, export, decision and decision.to_dict())
        self._submit_monitors(g, export)
        judged_as = (
            ""
            if method.trains_alone()
            else f"learner success {row['learner_success']:.0%} ± "
            f"{row['learner_success_se']:.0%}, collision {row['learner_collision']:.0%}, "
            f"return {row['learner_return']:.1f}; {method.verdict(c, decision)}; "
        )
        self.say(
            f"gen {g}: {judged_as}std {row.get('std_median', 0):.2f}; "
            f"oracle {oracle_s:.0f}s ({stats.env_steps_per_s:.0f} steps/s)"
        )

    def _submit_monitors(self, g: int, export: dict[str, Any] | None) -> None:
        """Start generation g's monitors (`hola_ray.methods.monitors`) of its learner's
        export and of the population as the coordinator holds it now."""
        members = None
        if not self.config.strategy.trains_alone():
            nodes = sorted(ray.get(self.coord.slots.remote()))
            members = self.exports(nodes)
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
        kept = "best so far" if best else f"best stays generation {self.run.best_generation()}"
        said = monitored(figures, row, self.config.env.n_pursuers)
        self.say(f"gen {g} monitored: {said}{kept if g >= 1 else ''}".rstrip("; "))
        return True

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
            self.say(f"best.pt written again from generation {best}")
        if self.run.learner_generation() != last:
            state = self.run.load_learner_state(last)
            decision = self.run.read_json(last, "state.json")["decision"]
            self.run.save_latest(last, self.config.method, self.config.export(state), decision)
            self.say(f"learner.pt written again from generation {last}")

    def _judge_in_population(self, g: int, export, learner_state, slot: int | None = None):
        """The Grapher weighs the learner's hyperedges; the coordinator decides (pbt: on
        the agent of `slot`)."""
        self.coord.set_phase.remote("grapher")
        with self.clock.phase("grapher"):
            files = TorchFile.of(export), TorchFile.of(learner_state)
            candidate = ray.get(self.coord.propose.remote(*files))
        results, grapher = self._grapher(g)
        self.coord.set_phase.remote("coordinator")
        with self.clock.phase("coordinator"):
            ray.get(self.coord.record.remote(results))
            decision = ray.get(self.coord.decide.remote(slot, g))
        judged = {
            **edge_summary("learner", results),
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
            exports = self.exports(nodes)
            return weigh(
                edges,
                exports,
                c.env,
                self.pool if c.grapher.workers else None,
                c.grapher.episodes_per_edge,
                lambda edge: edge_seed(c.seed, g, edge),
                c.grapher.chunks,
                desc=f"gen {g} grapher",
                progress=self.progress,
            )

    def _saved(self, g: int) -> None:
        interrupt.check()
        if self.saved is not None:
            self.saved(g)

    def context(self) -> Context:
        """What a method's hooks may use of this run."""
        return Context(
            config=self.config,
            run=self.run,
            zero=self.zero,
            say=self.say,
            progress=self.progress,
            coord=getattr(self, "coord", None),
            member_states=self.member_states,
        )

    def say(self, text: str) -> None:
        """One line of the run's log (a method's generation 0 says what it built here)."""
        print(text, flush=True)

    def exports(self, nodes: list[int]) -> dict[int, dict[str, Any]]:
        """The plain-torch exports of nodes, as the coordinator holds them."""
        return opened(self.coord.exports.remote(nodes))

    def member_states(self, nodes: list[int]) -> dict[int, dict[str, Any]]:
        """The RLlib module states of members, to seat them as partners or train on."""
        return opened(self.coord.member_states.remote(nodes))
