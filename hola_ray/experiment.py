"""The paper's experiment on Ray: every method × seed, then the zero-shot evaluation.

    python -m hola_ray.experiment --config configs/experiments/X.yaml [--out DIR]
    python -m hola_ray.experiment --resume DIR

An experiment config names a base run config, the methods (each with its own overrides
of the base), the seeds and the evaluation:

    base: configs/default.yaml        # relative to the repository root or to this file
    overrides: {env: {n_evaders: 2}}  # applied to every trial (optional)
    methods:                          # method → overrides for its trials ({} for none)
      hola: {}
      sp: {generations: 12}
      hola_long: {method: hola, pretrain: {env_steps: 1000000}}   # a variant: an ablation row
    seeds: [0, 1, 2]
    parallel: 0                       # trials started at once; 0: all (Ray runs those that fit)
    evaluation: {episodes: 50, seeds: [0, 1, 2], cell_episodes: 10, pools: [hot, het],
                 learner: final,      # final: learner.pt; best: best.pt
                 pairs: [[uniform, sp]]}  # differences beyond hola − every other method

Each trial (method × seed) is one `Trainer` run in `DIR/trials/<method>-s<seed>/`, run as a
Ray task in a placement group of its own: one bundle for the trial's process (its PPO
learner, with `oracle.gpus_per_learner` GPUs) and one CPU per env runner, packed onto one
node where one has room. The env runners and member actors the trial starts are placed in
that group (its coordinator, which holds no CPU, on the trial's own node), so a trial never
waits for a CPU another trial took. With `parallel: 0` every trial asks Ray for its group
at once: Ray runs as many as the CPUs hold and the rest wait for CPUs ("waiting for CPUs"
in the progress view), and on an autoscaling cluster their demand is what adds nodes;
`parallel: N` starts at most N at a time. A trial whose node cannot see DIR (a cluster
without a shared filesystem) trains in a staging folder there and mirrors it to DIR on the
driver's node after every generation (`hola_ray.mirror`). A trial whose run directory holds
its last generation is done and never rerun: `--resume DIR` skips it, continues a trial
that was cut short from its last complete generation and starts the rest. Then every
trial's learner is evaluated against the pools (`hola_ray.evaluate`, one Ray task per
trial, cached in `DIR/evaluation/` under the pools' manifest hashes, so a rebuilt pool is
evaluated again), and the experiment writes `DIR/results.json` (per trial, per method, and
the paired differences between methods), `DIR/results.md` and `DIR/figure.png` (the
paper's Fig. 4 layout and AT-Drone's two metrics, one bar per method: the mean over its
seeds, whiskers its 95 % interval). Intervals and differences: `hola_ray.evaluation.compare`
(a bootstrap over training seeds within each method and over episodes within each partner
combination; every trial plays the same episodes, so differences are paired).
While it runs, a line every few seconds (and `DIR/progress.json`) says which trials run,
wait or are done.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import sys
import time
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hola_ray.env.config import ConfigError, load_yaml
from hola_ray.methods.config import METHODS, RunConfig

ROOT = Path(__file__).resolve().parent.parent
CONFIG_NAME = "experiment.yaml"
METRICS = ("success", "collision", "length")


# ---- the config ---------------------------------------------------------------------------
@dataclass(frozen=True)
class EvaluationSettings:
    episodes: int = 50
    """episodes per evaluation seed, per pool"""
    seeds: tuple[int, ...] = (0, 1, 2)
    """evaluation seeds: the same episodes and partner draws for every trial"""
    cell_episodes: int = 10
    """episodes per BR-Prox score cell"""
    pools: tuple[str, ...] = ("hot", "het")
    learner: str = "final"
    """final: each trial's learner.pt; best: its best.pt"""
    pairs: tuple[tuple[str, str], ...] = ()
    """method pairs (A, B) whose difference A − B is reported, beside `hola` against every
    other method"""


@dataclass(frozen=True)
class Experiment:
    """A validated experiment config: one run config per trial, and the evaluation."""

    base: str
    methods: dict[str, dict[str, Any]]
    seeds: tuple[int, ...]
    overrides: dict[str, Any] = field(default_factory=dict)
    parallel: int = 0
    evaluation: EvaluationSettings = field(default_factory=EvaluationSettings)
    source: Path | None = None

    @classmethod
    def from_yaml(cls, path: str | Path) -> Experiment:
        path = Path(path)
        if not path.is_file():
            raise ConfigError(f"experiment config {path} does not exist")
        raw = load_yaml(path) or {}
        allowed = {"base", "overrides", "methods", "seeds", "parallel", "evaluation"}
        if not isinstance(raw, Mapping) or set(raw) - allowed:
            unknown = sorted(set(raw) - allowed) if isinstance(raw, Mapping) else raw
            raise ConfigError(f"{path}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
        for key in ("base", "methods", "seeds"):
            if key not in raw:
                raise ConfigError(f"{path}: `{key}` is required")
        methods = raw["methods"]
        if isinstance(methods, list):
            methods = dict.fromkeys(methods)
        if not isinstance(methods, Mapping) or not methods:
            raise ConfigError(f"{path}: methods must be a non-empty mapping method → overrides")
        for name, over in methods.items():
            method = (over or {}).get("method", name) if isinstance(over, Mapping) else name
            if method not in METHODS:
                raise ConfigError(
                    f"{path}: {name}: unknown method {method!r}; known: {sorted(METHODS)} (a "
                    "variant of a method names it in its overrides: `hola_long: {method: hola, …}`)"
                )
            if not isinstance(name, str) or "-s" in name or not name.replace("_", "").isalnum():
                raise ConfigError(
                    f"{path}: {name!r}: a method or variant name is letters, digits and _ only"
                )
        seeds = raw["seeds"]
        if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) for s in seeds):
            raise ConfigError(f"{path}: seeds must be a non-empty list of integers")
        ev = raw.get("evaluation") or {}
        bad = set(ev) - {f for f in EvaluationSettings.__dataclass_fields__}
        if bad:
            raise ConfigError(f"{path}: unknown evaluation key(s) {sorted(bad)}")
        ev = {k: tuple(v) if isinstance(v, list) else v for k, v in ev.items()}
        pairs = ev.get("pairs", ())
        if not all(
            isinstance(pair, list | tuple) and len(pair) == 2 and set(pair) <= set(methods)
            for pair in pairs
        ):
            raise ConfigError(
                f"{path}: evaluation.pairs must list [A, B] pairs of the experiment's methods"
            )
        ev["pairs"] = tuple(tuple(pair) for pair in pairs)
        evaluation = EvaluationSettings(**ev)
        if evaluation.learner not in ("final", "best"):
            raise ConfigError(f"{path}: evaluation.learner must be final or best")
        exp = cls(
            base=str(raw["base"]),
            methods={m: dict(o or {}) for m, o in methods.items()},
            seeds=tuple(seeds),
            overrides=dict(raw.get("overrides") or {}),
            parallel=int(raw.get("parallel", 0)),
            evaluation=evaluation,
            source=path,
        )
        for name in exp.trials():  # every trial's run config is valid before Ray starts
            try:
                exp.run_config(name)
            except ConfigError as err:
                raise ConfigError(f"{path}: trial {name}: {err}") from err
        return exp

    def base_path(self) -> Path:
        """The base run config: relative to the experiment file, else to the repository."""
        base = Path(self.base)
        if base.is_absolute():
            return base
        if self.source is not None and (self.source.parent / base).is_file():
            return self.source.parent / base
        return ROOT / base

    def pairs(self) -> list[tuple[str, str]]:
        """The differences reported: `hola` against every other method (the first method
        against the rest when there is no `hola`), then `evaluation.pairs`."""
        methods = list(self.methods)
        first = "hola" if "hola" in methods else methods[0]
        out = [(first, m) for m in methods if m != first]
        return out + [p for p in self.evaluation.pairs if p not in out]

    def trials(self) -> list[str]:
        """Trial names, method by method: `<method>-s<seed>`."""
        return [trial_name(m, s) for m in self.methods for s in self.seeds]

    def run_config(self, trial: str) -> RunConfig:
        method, seed = parse_trial(trial)
        base = load_yaml(self.base_path()) or {}
        merged = deep_merge(deep_merge(base, self.overrides), self.methods[method])
        merged.update(method=self.methods[method].get("method", method), seed=seed)
        return RunConfig.from_dict(merged)


def trial_name(method: str, seed: int) -> str:
    return f"{method}-s{seed}"


def parse_trial(trial: str) -> tuple[str, int]:
    method, _, seed = trial.rpartition("-s")
    return method, int(seed)


def deep_merge(base: Mapping[str, Any], patch: Mapping[str, Any]) -> dict[str, Any]:
    """`base` with `patch` laid over it, mappings merged key by key."""
    out = copy.deepcopy(dict(base))
    for key, value in patch.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


# ---- trials on Ray --------------------------------------------------------------------------
def trial_state(run_dir: Path, generations: int) -> tuple[str, int | None]:
    """('done' | 'partial' | 'new', last complete generation) of a trial's run directory.
    Done: its last generation is complete and so is learner.pt (written just after it)."""
    from hola_ray.population.rundir import RunDir

    run = RunDir(run_dir)
    last = run.last_completed()
    if last is None:
        return "new", None
    return ("done" if run.finished(generations) else "partial"), last


MARK = ".experiment"
"""DIR/.experiment: a token that says which nodes see the experiment's directory"""


def sees(run_dir: Path, token: str | None) -> bool:
    """Whether this node sees the experiment directory of `run_dir` (DIR/trials/<t>)."""
    mark = Path(run_dir).parent.parent / MARK
    try:
        return token is not None and mark.read_text() == token
    except OSError:
        return False


def _run_trial(
    config: dict[str, Any],
    run_dir: str,
    token: str | None = None,
    driver_node: str | None = None,
    seed: bytes | None = None,
    mirror: bool | None = None,
    adopt_from: Sequence[str] = (),
) -> str:
    """One trial. Where its node sees the experiment directory (one machine, or a shared
    filesystem), it trains there, taking generation 0 from a sibling trial that built the
    same one (`adopt_from`: the trials of its seed whose methods share MEP's population).
    Elsewhere it trains in a staging folder of its node (from `seed`, the driver's copy of
    a partial trial, if given) and mirrors it to the driver's node after every generation
    (`hola_ray.mirror`). Returns how it stored its folder."""
    import shutil
    import tempfile

    import ray
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    from hola_ray.methods.hola import Trainer
    from hola_ray.mirror import DirectorySync, Mirror, unpack

    root, run_config = Path(run_dir), RunConfig.from_dict(config)
    if mirror is None:
        mirror = not sees(root, token)
    if not mirror:
        donors = tuple(Path(d) for d in adopt_from)
        Trainer(run_config, root, progress=False, adopt_from=donors).fit()
        return "in place"
    staging = Path(tempfile.gettempdir()) / "hola_ray-trials" / str(token) / root.name
    if seed is not None:
        unpack(seed, staging)
    else:
        shutil.rmtree(staging, ignore_errors=True)
    where = NodeAffinitySchedulingStrategy(node_id=driver_node, soft=False)
    actor = Mirror.options(scheduling_strategy=where).remote(str(root))
    sync = DirectorySync(staging, actor)
    if seed is not None:
        sync.mark_seen()  # the driver has all of it already
    try:
        Trainer(run_config, staging, progress=False, saved=sync).fit()
        sync()
    finally:
        ray.kill(actor)
    shutil.rmtree(staging, ignore_errors=True)  # all of it is on the driver's node now
    return "mirrored to the driver's node"


def _reference(pool: str, settings: dict[str, Any], n_evaders: int) -> np.ndarray:
    """A pool's reference returns for the BR-Prox score: computed once, for every trial."""
    from hola_ray.env.config import PursuitConfig
    from hola_ray.evaluate import cell_returns, pools

    config = PursuitConfig(n_evaders=n_evaders)
    members = list(pools([pool], [], config)[pool].values())
    return cell_returns(members, members, config, settings["cell_episodes"], settings["seeds"])


def _evaluate_trial(
    learner: bytes, settings: dict[str, Any], n_evaders: int, references: dict[str, np.ndarray]
) -> dict[str, Any]:
    """A learner (its file's bytes, read by the driver: any node can evaluate it) against
    the pools."""
    import tempfile

    from hola_ray.env.config import PursuitConfig
    from hola_ray.evaluate import evaluate_learner, load_learner, pools

    config = PursuitConfig(n_evaders=n_evaders)
    members = pools(list(settings["pools"]), [], config)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "learner.pt"
        path.write_bytes(learner)
        _, policy = load_learner(path, config)
    return {
        pool: evaluate_learner(
            policy,
            list(members[pool].values()),
            references[pool],
            config,
            settings["episodes"],
            list(settings["seeds"]),
            settings["cell_episodes"],
        )
        for pool in settings["pools"]
    }


class Runner:
    """Runs an experiment's trials as Ray tasks, evaluates them and writes the results."""

    def __init__(self, experiment: Experiment, out: Path, say=print, poll_s: float = 5.0):
        self.exp = experiment
        self.out = Path(out)
        self.say = say
        self.poll_s = poll_s
        self.trials_dir = self.out / "trials"
        self.eval_dir = self.out / "evaluation"
        # every trial's run config, read once (the progress view polls every few seconds)
        self.configs = {t: experiment.run_config(t) for t in experiment.trials()}
        self.mirror: bool | None = None
        """None: each trial mirrors its folder to this node if its own node cannot see
        DIR (`sees`); True / False: always / never"""

    def token(self) -> str:
        """DIR/.experiment's token (made once): a trial's node that reads it sees DIR."""
        import uuid

        mark = self.out / MARK
        if not mark.is_file():
            self.out.mkdir(parents=True, exist_ok=True)
            mark.write_text(uuid.uuid4().hex)
        return mark.read_text()

    def trial_dir(self, trial: str) -> Path:
        return self.trials_dir / trial

    def states(self) -> dict[str, tuple[str, int | None]]:
        return {
            t: trial_state(self.trial_dir(t), self.configs[t].generations)
            for t in self.exp.trials()
        }

    def bundles(self, trial: str) -> list[dict[str, float]]:
        """A trial's placement group: its own process (the PPO learner, with its GPUs) and
        one CPU per env runner."""
        oracle = self.configs[trial].oracle
        head = {"CPU": 1.0} | ({"GPU": oracle.gpus_per_learner} if oracle.gpus_per_learner else {})
        return [head] + [{"CPU": 1.0} for _ in range(oracle.env_runners)]

    def needs(self, trial: str) -> dict[str, float]:
        """A trial's CPUs and GPUs, all its bundles together."""
        return {r: sum(b.get(r, 0.0) for b in self.bundles(trial)) for r in ("CPU", "GPU")}

    def parallel(self) -> int:
        """Trials started at once: the config's `parallel`, else all of them (their
        placement groups wait in Ray until CPUs are free, or an autoscaler adds nodes)."""
        return self.exp.parallel if self.exp.parallel > 0 else len(self.exp.trials())

    def fit_now(self) -> int:
        """How many trials the cluster's CPUs (and GPUs, for trials that want them) hold
        side by side as it is now."""
        import ray

        have = ray.cluster_resources()
        width = len(self.exp.trials())
        for t in self.exp.trials():
            for resource, need in self.needs(t).items():
                if need > 0:
                    width = min(width, int(have.get(resource, 0.0) // need))
        return max(1, width)

    def place(self, trial: str) -> tuple[Any, dict[str, Any]]:
        """Reserve a trial's placement group. The trial's task takes the first bundle and
        the env runners and members it starts are captured in the group."""
        from ray.util.placement_group import placement_group
        from ray.util.scheduling_strategies import PlacementGroupSchedulingStrategy

        bundles = self.bundles(trial)
        group = placement_group(bundles, strategy="PACK")
        strategy = PlacementGroupSchedulingStrategy(
            group, placement_group_bundle_index=0, placement_group_capture_child_tasks=True
        )
        head = bundles[0]
        options = {"num_cpus": head["CPU"], "scheduling_strategy": strategy}
        if head.get("GPU"):
            options["num_gpus"] = head["GPU"]
        return group, options

    def _check_fits(self, trials: Sequence[str]) -> None:
        """Say so at once when a trial's group cannot fit the cluster as it is now (it then
        waits for nodes to join, as an autoscaling cluster's would)."""
        import ray

        have = ray.cluster_resources()
        for t in trials:
            for resource, need in self.needs(t).items():
                if need > have.get(resource, 0.0):
                    self.say(
                        f"warning: {t} needs {need:g} {resource}(s) and the cluster has "
                        f"{have.get(resource, 0.0):g}: it waits until nodes join"
                    )

    # ---- phase 1: training ------------------------------------------------------------------
    trial_fn = staticmethod(_run_trial)

    def train(self) -> None:
        import ray

        from hola_ray.mirror import pack

        states = self.states()
        todo = [t for t, (s, _) in states.items() if s != "done"]
        for t, (s, last) in states.items():
            if s == "done":
                self.say(f"{t}: done (generation {last}), not rerun")
            elif s == "partial":
                self.say(f"{t}: resumes after generation {last}")
        if not todo:
            return
        remote = ray.remote(max_retries=0)(self.trial_fn)
        width = self.parallel()
        self.say(
            f"training {len(todo)} trial(s), "
            + (f"{width} at a time" if self.exp.parallel else "all asking Ray for CPUs at once")
            + f"; this cluster holds {self.fit_now()} side by side now"
        )
        self._check_fits(todo)
        token, here = self.token(), ray.get_runtime_context().get_node_id()
        running: dict[Any, str] = {}
        groups: dict[str, Any] = {}
        placing: dict[str, Any] = {}  # trial → its group's ready(), until the group is placed
        started: dict[str, float] = {}
        failed: dict[str, str] = {}
        waiting = list(todo)
        last_view, last_line = 0.0, ""
        try:
            while waiting or running:
                while waiting and len(running) < width:
                    t = waiting.pop(0)
                    groups[t], options = self.place(t)
                    placing[t] = groups[t].ready()
                    # a partial trial starts from the driver's copy wherever it lands
                    partial = states[t][0] == "partial"
                    ref = remote.options(**options).remote(
                        self.configs[t].to_dict(),
                        str(self.trial_dir(t).resolve()),
                        token,
                        here,
                        pack(self.trial_dir(t)) if partial else None,
                        self.mirror,
                        self.donors(t),
                    )
                    running[ref] = t
                    started[t] = time.monotonic()
                ready, _ = ray.wait(list(running), num_returns=1, timeout=self.poll_s)
                for ref in ready:
                    t = running.pop(ref)
                    try:
                        how = ray.get(ref)
                        took = time.monotonic() - started[t]
                        self.say(f"{t}: done in {took / 60:.1f} min ({how})")
                    except Exception as err:  # noqa: BLE001 - one failed trial must not stop the rest
                        failed[t] = f"{type(err).__name__}: {str(err).splitlines()[-1][:300]}"
                        self.say(f"{t}: FAILED: {failed[t]}")
                    ray.util.remove_placement_group(groups.pop(t))
                    placing.pop(t, None)
                for t, ref in list(placing.items()):
                    if ray.wait([ref], timeout=0)[0]:
                        del placing[t]
                line = self.view(running.values(), waiting, failed, placing)
                # say it when it changed, and at least once a minute
                if line != last_line or time.monotonic() - last_view >= 60.0:
                    self.say(f"[{time.strftime('%H:%M:%S')}] {line}")
                    last_view, last_line = time.monotonic(), line
        finally:
            for group in groups.values():
                ray.util.remove_placement_group(group)
        if failed:
            raise RuntimeError(
                f"{len(failed)} trial(s) failed: {', '.join(failed)}; fix and run "
                f"`python -m hola_ray.experiment --resume {self.out}`"
            )

    def view(
        self,
        running: Sequence[str],
        waiting: Sequence[str],
        failed: Mapping[str, str],
        placing: Collection[str] = (),
    ) -> str:
        """DIR/progress.json and a progress line: which trials run, wait for their CPUs
        (`placing`: started, their placement group not yet placed), wait or are done."""
        states = self.states()
        rows = {}
        for t, (s, last) in states.items():
            total = self.configs[t].generations
            if t in failed:
                status = "failed"
            elif s == "done":
                status = "done"
            elif t in placing:
                status = "placing"
            elif t in running:
                status = "running"
            else:
                status = "waiting"
            rows[t] = {"status": status, "generation": last, "generations": total}
        _atomic_json(self.out / "progress.json", rows)
        counts = {k: sum(r["status"] == k for r in rows.values()) for k in ("done", "running")}
        busy = ", ".join(
            f"{t} gen {rows[t]['generation'] if rows[t]['generation'] is not None else '-'}"
            f"/{rows[t]['generations']}"
            for t in running
            if t not in placing
        )
        return (
            f"trials: {counts['done']} done, {counts['running']} running ({busy or 'none'}), "
            + (f"{len(placing)} waiting for CPUs ({', '.join(placing)}), " if placing else "")
            + f"{len(waiting)} waiting"
            + (f", {len(failed)} failed" if failed else "")
        )

    # ---- phase 2: evaluation ----------------------------------------------------------------
    def learner_file(self, trial: str) -> Path:
        root = self.trial_dir(trial)
        return root / ("best.pt" if self.exp.evaluation.learner == "best" else "learner.pt")

    def evaluate(self) -> dict[str, dict[str, Any]]:
        import ray

        self.eval_dir.mkdir(parents=True, exist_ok=True)
        from hola_ray.evaluate import pool_fingerprints

        settings = {
            "episodes": self.exp.evaluation.episodes,
            "seeds": list(self.exp.evaluation.seeds),
            "cell_episodes": self.exp.evaluation.cell_episodes,
            "pools": list(self.exp.evaluation.pools),
            "format": EVALUATION_FORMAT,
            "pool_manifests": pool_fingerprints(self.exp.evaluation.pools),
        }
        results: dict[str, dict[str, Any]] = {}
        todo: list[str] = []
        for t in self.exp.trials():
            cached = self.eval_dir / f"{t}.json"
            if cached.is_file():
                saved = json.loads(cached.read_text())
                if saved.get("settings") == settings:
                    results[t] = saved["pools"]
                    continue
            todo.append(t)
        if not todo:
            return {t: results[t] for t in self.exp.trials()}
        scenarios = {self.configs[t].env.n_evaders for t in todo}
        if len(scenarios) > 1:
            raise RuntimeError(f"the trials play different numbers of evaders {scenarios}")
        evaders = scenarios.pop()
        self.say(
            f"evaluating {len(todo)} learner(s) against {', '.join(settings['pools'])}: "
            "the pools' reference returns first"
        )
        start = time.monotonic()
        reference = ray.remote(num_cpus=1, max_retries=1)(_reference)
        refs = {p: reference.remote(p, settings, evaders) for p in settings["pools"]}
        references = ray.put({p: ray.get(r) for p, r in refs.items()})
        self.say(f"reference returns: {time.monotonic() - start:.0f} s")
        remote = ray.remote(num_cpus=1, max_retries=1)(_evaluate_trial)
        pending: dict[Any, str] = {
            remote.remote(self.learner_file(t).read_bytes(), settings, evaders, references): t
            for t in todo
        }
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            t = pending.pop(ready[0])
            results[t] = ray.get(ready[0])
            _atomic_json(self.eval_dir / f"{t}.json", {"settings": settings, "pools": results[t]})
            figures = "; ".join(
                f"{p} success {r['success']:.1%}, collision {r['collision']:.1%}"
                for p, r in results[t].items()
            )
            self.say(f"{t}: {figures}")
        return {t: results[t] for t in self.exp.trials()}

    # ---- phase 3: results -------------------------------------------------------------------
    def write_results(self, per_trial: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        from hola_ray.evaluate import plot
        from hola_ray.evaluation.compare import METRICS

        methods, differences = aggregate(per_trial, list(self.exp.methods), self.exp.pairs())
        trials = {
            t: {
                "method": parse_trial(t)[0],
                "seed": parse_trial(t)[1],
                **self.budget_spent(t),
                "pools": {
                    p: {k: r[k] for k in METRICS}
                    | {f"{k}_se": r[f"{k}_se"] for k in METRICS}
                    | {"score": r["score_iqm"]}
                    for p, r in pools_.items()
                },
            }
            for t, pools_ in per_trial.items()
        }
        results = {
            "experiment": str(self.exp.source) if self.exp.source else None,
            "base": self.exp.base,
            "seeds": list(self.exp.seeds),
            "evaluation": {
                "episodes_per_seed": self.exp.evaluation.episodes,
                "seeds": list(self.exp.evaluation.seeds),
                "learner": self.exp.evaluation.learner,
            },
            "trials": trials,
            "methods": methods,
            "differences": differences,
            "intervals": "95 %, stratified bootstrap: training seeds within each method, "
            "episodes within each partner combination, shared by every trial (paired)",
        }
        _atomic_json(self.out / "results.json", results)
        figure_input = {
            m: {p: {**r, "score_iqm": r["score"]} for p, r in pools_.items()}
            for m, pools_ in methods.items()
        }
        png, _ = plot(figure_input, self.out)
        png.replace(self.out / "figure.png")
        (self.out / "evaluation.md").unlink(missing_ok=True)
        (self.out / "results.md").write_text(
            results_table(figure_input, differences, len(self.exp.seeds))
        )
        return results

    def donors(self, trial: str) -> list[str]:
        """The other trials whose generation 0 this trial may take: the same
        `generation_zero_key` (seed, scenario, PPO and pre-training settings)."""
        key = self.configs[trial].generation_zero_key()
        if key is None:
            return []
        return [
            str(self.trial_dir(t).resolve())
            for t, c in self.configs.items()
            if t != trial and c.generation_zero_key() == key
        ]

    def budget_spent(self, trial: str) -> dict[str, Any]:
        """What a trial's training took: env steps, the learner's own transitions and
        gradient steps (cumulative, at its last generation), pre-training env steps, and the
        wall time of all its generations."""
        from hola_ray.population.rundir import RunDir

        rows = RunDir(self.trial_dir(trial)).metrics_rows()
        if not rows:
            return {}
        last = rows[-1]

        def number(row, key):
            value = row.get(key, "")
            return float(value) if value not in ("", None) else 0.0

        return {
            "env_steps": int(number(last, "env_steps")),
            "learner_samples": int(number(last, "learner_samples")),
            "gradient_steps": int(number(last, "gradient_steps")),
            "pretrain_env_steps": int(number(rows[0], "pretrain_env_steps")),
            "train_s": round(
                sum(
                    # a generation's wall time; older runs and generation 0: its phases
                    number(r, "wall_s")
                    or sum(number(r, k) for k in ("pretrain_s", "oracle_s", "grapher_s", "eval_s"))
                    for r in rows
                ),
                1,
            ),
        }

    def run(self) -> dict[str, Any]:
        self.train()
        per_trial = self.evaluate()
        results = self.write_results(per_trial)
        self.say(f"wrote {self.out / 'results.json'}, results.md and figure.png")
        return results


EVALUATION_FORMAT = 2
"""the layout of a cached trial evaluation (2: every episode's record, for the bootstrap)"""


def aggregate(
    per_trial: Mapping[str, Mapping[str, Mapping[str, Any]]],
    methods: Sequence[str],
    pairs: Sequence[tuple[str, str]] = (),
) -> tuple[dict[str, dict[str, dict[str, Any]]], dict[str, dict[str, dict[str, Any]]]]:
    """Per method and pool: every metric's mean over the method's seeds with its standard
    error (`_se`) and 95 % interval (`_ci95`), and the BR-Prox score's mean over seeds; per
    pair "A-B" and pool, each metric's paired difference {mean, se, ci95}. Intervals and
    standard errors from `hola_ray.evaluation.compare` (training seeds and episodes)."""
    from hola_ray.evaluation.compare import METRICS, compare

    pools_ = sorted({p for r in per_trial.values() for p in r}, key=lambda p: (p != "hot", p))
    out: dict[str, dict[str, dict[str, Any]]] = {m: {} for m in methods}
    differences: dict[str, dict[str, dict[str, Any]]] = {f"{a}-{b}": {} for a, b in pairs}
    for pool in pools_:
        rows = {
            m: [r[pool] for t, r in per_trial.items() if parse_trial(t)[0] == m and pool in r]
            for m in methods
        }
        rows = {m: rs for m, rs in rows.items() if rs}
        episodes = {
            m: [{k: np.asarray(v) for k, v in r["per_episode"].items()} for r in rs]
            for m, rs in rows.items()
        }
        wanted = [(a, b) for a, b in pairs if a in rows and b in rows]
        figures, diffs = compare(episodes, wanted)
        for m, rs in rows.items():
            entry: dict[str, Any] = {"trials": len(rs)}
            for k in METRICS:
                entry[k] = figures[m][k]["mean"]
                entry[f"{k}_se"] = figures[m][k]["se"]
                entry[f"{k}_ci95"] = figures[m][k]["ci95"]
            scores = np.array([r["score_iqm"] for r in rs], dtype=np.float64)
            entry["score"] = float(scores.mean())
            entry["score_se"] = (
                float(scores.std(ddof=1) / np.sqrt(scores.size)) if scores.size > 1 else 0.0
            )
            out[m][pool] = entry
        for (a, b), key in zip(wanted, diffs, strict=True):
            differences[f"{a}-{b}"][pool] = diffs[key]
    return out, differences


def results_table(
    methods: Mapping[str, Mapping[str, Mapping[str, Any]]],
    differences: Mapping[str, Mapping[str, Mapping[str, Any]]],
    seeds: int,
) -> str:
    """results.md: every method's figures, then the paired differences with a verdict."""
    from hola_ray.evaluate import table_lines
    from hola_ray.evaluation.compare import HIGHER_IS_BETTER, verdict

    lines = [
        f"Mean over {seeds} training seed(s) per method; [95 % interval]: a stratified "
        "bootstrap over training seeds (within each method) and evaluation episodes (within "
        "each partner combination). Steps to success: mean length of the successful "
        "episodes (AT-Drone's AST); reward: mean per-pursuer return (REW).",
        "",
        *table_lines(methods, "method"),
        "",
        "Paired differences A − B on the same episodes, [95 % interval]. An interval that "
        "contains zero is a tie.",
        "",
        "| A − B | pool | success | collision | length | learner crashed |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for pair, by_pool in differences.items():
        a = pair.split("-")[0]
        for pool, diff in by_pool.items():
            cells = []
            for m in ("success", "collision", "length", "learner_crash"):
                d = diff[m]
                lo, hi = d["ci95"]
                word = verdict(d, HIGHER_IS_BETTER[m])
                word = "tie" if word == "tie" else f"{a} {word}"
                if m == "length":
                    cells.append(f"{d['mean']:+.1f} [{lo:+.1f}, {hi:+.1f}] {word}")
                else:
                    cells.append(f"{d['mean']:+.1%} [{lo:+.1%}, {hi:+.1%}] {word}")
            lines.append(f"| {pair} | {pool} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _atomic_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)


# ---- command line ---------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m hola_ray.experiment", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--config", type=Path, help="experiment YAML (configs/experiments/)")
    parser.add_argument("--out", type=Path, help="experiment directory (default runs/<name>-…)")
    parser.add_argument("--resume", type=Path, metavar="DIR", help="continue an experiment")
    parser.add_argument("--num-cpus", type=int, help="CPUs of the local Ray (default: all)")
    args = parser.parse_args(argv)
    try:
        if args.resume is not None:
            if args.config is not None or args.out is not None:
                raise ConfigError("--resume DIR takes the experiment's own config; drop --config")
            saved = args.resume / CONFIG_NAME
            if not saved.is_file():
                raise ConfigError(f"--resume {args.resume}: no {CONFIG_NAME} there")
            experiment, out = Experiment.from_yaml(saved), args.resume
        elif args.config is None:
            raise ConfigError("give --config configs/experiments/X.yaml or --resume DIR")
        else:
            experiment = Experiment.from_yaml(args.config)
            out = args.out or Path("runs") / time.strftime(f"{args.config.stem}-%Y%m%d-%H%M%S")
            if (out / CONFIG_NAME).is_file():
                raise ConfigError(f"{out} already holds an experiment; continue it with --resume")
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.resume is None:
        out.mkdir(parents=True, exist_ok=True)
        # the base is resolved now, so that the saved copy does not depend on where it lives
        saved = {
            "base": str(experiment.base_path().resolve()),
            "overrides": experiment.overrides,
            "methods": experiment.methods,
            "seeds": list(experiment.seeds),
            "parallel": experiment.parallel,
            "evaluation": {
                k: [list(x) if isinstance(x, tuple) else x for x in v]
                if isinstance(v, tuple)
                else v
                for k, v in experiment.evaluation.__dict__.items()
            },
        }
        (out / CONFIG_NAME).write_text(yaml.safe_dump(saved, sort_keys=False))
    from hola_ray.population.coordinator import NAMESPACE
    from hola_ray.progress import init_ray

    init_ray(NAMESPACE, args.num_cpus)
    trials = experiment.trials()
    print(
        f"experiment in {out}: {len(experiment.methods)} method(s) × {len(experiment.seeds)} "
        f"seed(s) = {len(trials)} trials; base {experiment.base}",
        flush=True,
    )
    try:
        Runner(experiment, out, say=lambda s: print(s, flush=True)).run()
    except RuntimeError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


def script() -> None:
    """`hola-experiment` (`[project.scripts]`): `main` under the fixed hash seed, as `python -m
    hola_ray.experiment` runs it (`hola_ray.progress.fixed_hash_seed`)."""
    from hola_ray.progress import fixed_hash_seed

    fixed_hash_seed("hola_ray.experiment", sys.argv[1:])
    sys.exit(main())


if __name__ == "__main__":
    script()
