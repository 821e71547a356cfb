"""The coordinator: a named Ray actor that owns the HyFoG and the population.

It holds the `Population`, asks the method's `Rules` for φ and for the verdict on each
generation's candidate, persists the run after every generation, and exports generation,
learner success and φ entropy with `ray.util.metrics` (Ray dashboard / Prometheus). The
decisions live in the pure `Population` and `Rules`; this actor passes calls through and
does the I/O.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import ray

from hola_ray.config.population import PopulationConfig
from hola_ray.population.files import TorchFile
from hola_ray.population.rules import Rules, Uniform
from hola_ray.population.rundir import RunDir
from hola_ray.population.state import Decision, EdgeResult, Population
from hola_ray.population.telemetry import Telemetry

INITIAL_EDGES_STREAM = 3
"""the generator stream of G_0's thinning (`grapher.initial_edges`); a generation's
candidate hyperedges and decisions draw on streams 1 and 2"""


def run_id(run_dir: str) -> str:
    """A run's name on the cluster: its folder name and a hash of its full path, so that two
    runs in folders of one name under different parents never share actor names."""
    import hashlib

    path = Path(run_dir).resolve()
    return f"{path.name}-{hashlib.blake2b(str(path).encode(), digest_size=4).hexdigest()}"


def coordinator_name(run_dir: str) -> str:
    """The coordinator's actor name for a run directory: `coordinator:<run id>`."""
    return f"coordinator:{run_id(run_dir)}"


def phi_entropy(phi: Mapping[Any, float]) -> float:
    """Shannon entropy of φ in nats (log |V| when uniform)."""
    p = np.array([v for v in phi.values() if v > 0], dtype=np.float64)
    return float(-(p * np.log(p)).sum()) if p.size else 0.0


def total_variation(p: Mapping[int, float], q: Mapping[int, float]) -> float:
    """½ Σ |p − q| over the nodes of either distribution (0: the same draw; 1: disjoint)."""
    return 0.5 * sum(abs(p.get(v, 0.0) - q.get(v, 0.0)) for v in set(p) | set(q))


def phi_distances(
    phi: Mapping[int, float], population: Population, rival: Rules, exclude_slot: int | None
) -> dict[str, float]:
    """How far a generation's φ lies from its rival rule's (`phi_tv`) and from uniform draws
    over the same members (`phi_tv_uniform`), as total variation."""
    return {
        "phi_tv": total_variation(phi, rival.phi(population, exclude_slot)),
        "phi_tv_uniform": total_variation(phi, Uniform().phi(population, exclude_slot)),
    }


def saved_population(
    state: Mapping[str, Any], config: PopulationConfig, sizes: tuple[int, ...] | None = None
) -> Population:
    """The population a run goes on with from a saved generation (its `state.json`): its
    members and hyperedges, under the run's own open-ended settings (m, size). A generation 0
    adopted from a shipped build or another run so keeps the members, not that build's m or
    size (a run with m 4 on a build made with m 3 accepted only by 3). `sizes`: the run's
    hyperedge sizes, which the saved ones must be (a G_0 weighed for other teams is not
    this run's)."""
    population = Population.from_dict(state["population"])
    if sizes is not None and tuple(sizes) != population.sizes:
        raise ValueError(
            f"the saved population's hyperedges are teams of {list(population.sizes)}; this "
            f"run flies teams of {list(sizes)} (env.team): build its generation 0 for them"
        )
    if len(population.slots) > config.max_size:
        raise ValueError(
            f"the saved population holds {len(population.slots)} members, more than "
            f"population.max_size {config.max_size}"
        )
    population.max_size, population.top_m = config.max_size, config.top_m
    population.preferred_only = config.preferred_only
    return population


@dataclass(frozen=True)
class CoordinatorSettings:
    """What a run's coordinator decides by, from the run's config (no defaults of its own)."""

    rules: Rules
    """the method's φ and acceptance rule"""
    population: PopulationConfig
    l: int  # noqa: E741 - the paper's l
    """hyperedge size (the team's pursuers)"""
    seed: int
    """the run's seed: the sampled hyperedges' and decisions' generators"""
    edges_per_learner: int
    """grapher.edges_per_learner: (l − 1)-sets sampled per learner, 0 = every one"""
    initial_edges: int
    """grapher.initial_edges: G_0's hyperedges kept when the run goes on from generation 0,
    0 = every one"""
    method: str
    rival: Rules | None = None
    """the rule whose φ each generation's is compared with (`phi_tv`), if any; where there
    is one, uniform draws too (`phi_tv_uniform`)"""
    tags: Mapping[str, str] = field(default_factory=dict)
    """the telemetry's run and trial tags; empty: the run directory's own"""
    sizes: tuple[int, ...] = ()
    """the hyperedges' sizes, for teams of several (contract §6.2); empty: (l,)"""


@ray.remote(num_cpus=0, max_restarts=0)
class Coordinator:
    """Owns `Population` and the run directory; one per run, named `coordinator:<run>`."""

    def __init__(self, run_dir: str, settings: CoordinatorSettings):
        self.rules, self.seed, self.method = settings.rules, settings.seed, settings.method
        self.edges_per_learner = settings.edges_per_learner
        self.rival = settings.rival
        l, population, tags = settings.l, settings.population, settings.tags  # noqa: E741
        self._phi_tv: dict[str, float] = {}
        self.run = RunDir(run_dir)
        self.run.clean_partial()
        self.generation = self.run.last_completed()
        if self.generation is None:
            self.population = Population(
                l,
                population.max_size,
                population.top_m,
                population.preferred_only,
                settings.sizes or None,
            )
            self.last_metrics: dict[str, Any] = {}
        else:
            state = self.run.read_json(self.generation, "state.json")
            self.population = saved_population(state, population, settings.sizes or (l,))
            if self.generation == 0:  # the same draw on every start from generation 0
                rng = np.random.default_rng([self.seed, 0, INITIAL_EDGES_STREAM])
                self.population.thin(settings.initial_edges, rng)
            self.rules.setup(self.population)  # one adopted from another method's build
            self.last_metrics = self.run.metrics(self.generation)
        self.phase = "idle"
        self._edges: list[EdgeResult] = []
        self._pending: dict[int, tuple[TorchFile, TorchFile]] = {}  # node → export, state
        self.telemetry = Telemetry(
            self.run.tensorboard, tags or {"run": run_id(str(self.run.root)), "trial": ""}
        )
        """the run's figures as Ray metrics and TensorBoard events (`tags`: run, trial)"""

    def __repr__(self) -> str:
        """The dashboard's Repr column (`ray list actors --detail`: repr_name). Ray takes it
        once, when the actor starts: the state the run starts or resumes from; the live
        figures are its metrics (`hola_ray.population.telemetry`) and `status --live`."""
        if not hasattr(self, "telemetry"):  # Ray asks after an __init__ that failed, too
            return "coordinator (not started)"
        last = self.last_metrics
        if self.generation is None:
            state = "starting at generation 0"
        else:
            state = (
                f"generation {self.generation}, {len(self.population.members)} members, "
                f"φ entropy {float(last.get('phi_entropy', 0.0)):.3f}"
            )
            if last.get("accepted") not in (None, ""):
                node = last.get("candidate")
                state += f", last: {f'accepted as node {node}' if last['accepted'] else 'rejected'}"
        tags = self.telemetry.tags
        name = tags["run"] + (f"/{tags['trial']}" if tags["trial"] else "")
        return f"coordinator:{name} ({self.method}; {state})"

    # ---- the generation's steps ---------------------------------------------------------
    def last_completed(self) -> int | None:
        return self.generation

    def set_phase(self, phase: str) -> None:
        self.phase = phase

    def init_population(
        self, exports: Sequence[TorchFile], states: Sequence[TorchFile]
    ) -> list[int]:
        """Seat the initial members (generation 0): each one's export and RLlib state."""
        nodes = self.population.add_initial(len(exports))
        for node, export, state in zip(nodes, exports, states, strict=True):
            self._pending[node] = (export, state)
        self.rules.setup(self.population)
        return nodes

    def propose(self, export: TorchFile, state: TorchFile) -> int:
        """Add the learner's snapshot as this generation's candidate node."""
        node = self.population.propose()
        self._pending[node] = (export, state)
        return node

    def edges_to_evaluate(self, generation: int) -> list[tuple[int, ...]]:
        """G_0's hyperedges at generation 0; the candidate's sampled ones after."""
        if generation == 0:
            return self.population.initial_edges()
        rng = np.random.default_rng([self.seed, generation, 1])
        return self.population.candidate_edges(self.edges_per_learner, rng)

    def exports(self, nodes: Sequence[int]) -> dict[int, TorchFile]:
        """Plain-torch exports of nodes (pending ones from memory, members from disk)."""
        return self._weights(nodes, 0)

    def member_states(self, nodes: Sequence[int]) -> dict[int, TorchFile]:
        """RLlib module states of members, to seat them as frozen partners."""
        return self._weights(nodes, 1)

    def _weights(self, nodes: Sequence[int], which: int) -> dict[int, TorchFile]:
        path = (self.run.member_export, self.run.member_state)[which]
        pending = self._pending
        return {v: pending[v][which] if v in pending else TorchFile.read(path(v)) for v in nodes}

    def record(self, results: Sequence[EdgeResult]) -> None:
        self.population.record(results)
        self._edges = list(results)

    def decide(self, slot: int | None = None, generation: int = 0) -> Decision:
        """The method's verdict on the candidate (`slot`: the agent it was trained from). A
        candidate that copied a member's weights (PBT's exploit) takes that member's files;
        one turned away leaves nothing behind."""
        rng = np.random.default_rng([self.seed, generation, 2])
        decision = self.rules.decide(self.population, slot, rng)
        source = decision.copied_from
        if source is not None:
            files = self._weights([source], 0)[source], self._weights([source], 1)[source]
            self._pending[decision.candidate] = files
        elif not decision.accepted:
            self._pending.pop(decision.candidate, None)
        return decision

    def agent_hyper(self, slot: int) -> dict[str, float]:
        """pbt: the PPO hyperparameters the agent of `slot` trains with."""
        return dict(self.population.extra["agent_hyper"][str(slot)])

    def commit(
        self,
        generation: int,
        metrics: Mapping[str, Any],
        decision: Decision | None = None,
        iterations: Sequence[Mapping[str, float]] = (),
        learner: tuple[TorchFile, TorchFile, TorchFile] | None = None,
    ) -> dict[str, Any]:
        """Persist generation `generation` (its metrics and the Oracle's per-iteration log;
        `learner`: the learner's RLlib state, export and training state) and publish its
        metrics; returns the metrics row."""
        start = time.perf_counter()
        for node, (export, state) in self._pending.items():
            if node in self.population.slots:
                self.run.save_member(node, export, state)
        self._pending.clear()
        phi = self.rules.phi(self.population)
        eta = self.population.eta()
        row = dict(metrics)
        accepted = int(bool(row.get("accepted", 0)))
        row.update(
            generation=generation,
            population_size=len(self.population.members),
            phi_entropy=phi_entropy(phi),
            acceptances=int(self.last_metrics.get("acceptances", 0)) + accepted,
        )
        files = {
            "state.json": {
                "generation": generation,
                "population": self.population.to_dict(),
                "decision": decision.to_dict() if decision else None,
            },
            "hyfog.json": self.population.hyfog.to_dict(),
            "phi.json": {str(k): v for k, v in phi.items()},
            "eta.json": {str(k): v for k, v in eta.items()},
            "edges.json": [vars(r) | {"nodes": list(r.nodes)} for r in self._edges],
        }
        # the φ this generation trained with, against the rival's and against uniform draws
        row.update({key: round(tv, 6) for key, tv in self._phi_tv.items()})
        self._phi_tv = {}
        row["persist_s"] = round(time.perf_counter() - start, 4)
        files["metrics.json"] = row
        files["iterations.json"] = [dict(r) for r in iterations]
        self.run.write_generation(generation, files, *(learner or (None, None, None)))
        if self.population.members:
            self.run.write_population(
                {
                    v: {"slot": self.population.slots[v], "eta": eta.get(v), "phi": phi.get(v)}
                    for v in self.population.members
                },
                generation,
            )
        self.run.rewrite_metrics_csv()
        self.generation = generation
        self.last_metrics = row
        self._edges = []
        self.telemetry.row(row, iterations)
        return row

    def complete(self, generation: int, figures: Mapping[str, Any]) -> None:
        """Write generation `generation`'s monitored figures beside it (`RunDir.complete`)
        and publish them."""
        self.run.complete(generation, figures)
        if generation == self.generation:
            self.last_metrics = {**self.last_metrics, **figures}
        self.telemetry.monitors(generation, figures)

    # ---- views --------------------------------------------------------------------------
    def slots(self) -> dict[int, int]:
        return dict(self.population.slots)

    def plan(self, exclude_slot: int | None = None) -> dict[int, tuple[int, float]]:
        """What the Oracle's partner slots hold this generation: slot → (member node, φ), in
        the members' order; φ 0 for the member in `exclude_slot` (PBT's agent in training)."""
        phi = self.rules.phi(self.population, exclude_slot)
        if self.rival is not None:
            self._phi_tv = phi_distances(phi, self.population, self.rival, exclude_slot)
        return {self.population.slots[v]: (v, phi.get(v, 0.0)) for v in self.population.members}

    def view(self) -> dict[str, Any]:
        """The live status: generation, phase, members with slot, η, φ, value; metrics."""
        phi, eta = self.rules.phi(self.population), self.population.eta()
        values = self.rules.values(self.population)
        return {
            "run_dir": str(self.run.root),
            "generation": self.generation,
            "phase": self.phase,
            "method": self.method,
            "members": [
                {
                    "node": v,
                    "slot": self.population.slots[v],
                    "eta": eta.get(v),
                    "phi": phi.get(v),
                    "value": values.get(v),
                }
                for v in self.population.members
            ],
            "last_metrics": self.last_metrics,
        }

    def close(self) -> None:
        self.telemetry.close()


def start_coordinator(run_dir: Path, settings: CoordinatorSettings) -> Any:
    """The coordinator of the run in `run_dir`, named for the folder and placed on this
    node: it writes the folder this driver reads."""
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    from hola_ray.process import NAMESPACE

    here = ray.get_runtime_context().get_node_id()
    return Coordinator.options(
        name=coordinator_name(str(run_dir)),
        namespace=NAMESPACE,
        scheduling_strategy=NodeAffinitySchedulingStrategy(node_id=here, soft=False),
    ).remote(str(Path(run_dir).resolve()), settings)


def opened(files: Any) -> dict[int, dict[str, Any]]:
    """What the coordinator's `exports` or `member_states` (an object ref) gave, opened here."""
    return {v: f.load() for v, f in ray.get(files).items()}
