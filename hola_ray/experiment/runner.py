"""The experiment's driver: `Runner` trains every trial as a Ray task in a placement group
of its own, evaluates the learners against the pools and writes the results."""

from __future__ import annotations

import json
import time
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

from hola_ray.config.scenario import PursuitConfig
from hola_ray.experiment.config import Experiment, parse_trial, trial_name
from hola_ray.experiment.inflight import InFlight
from hola_ray.experiment.report import budget_spent, write_results
from hola_ray.experiment.results import EVALUATION_FORMAT, _atomic_json, build_label
from hola_ray.experiment.tasks import MARK, _evaluate_trial, _reference, _run_trial, trial_state


def time_left(elapsed_s: float, trained: int, left: int) -> str | None:
    """'about 9.5 h of training left (this run: 12 generations in 15 min)': the generations
    still to train at the pace of those trained since this run started; None before its
    first. A generation counts alike whatever its method (generation 0's pre-training and
    FCP's agents aside), so it is a pace, not a promise."""
    if trained <= 0 or left <= 0:
        return None

    def span(s: float) -> str:
        return f"{s / 3600:.1f} h" if s >= 5400 else f"{max(1, round(s / 60))} min"

    return (
        f"about {span(elapsed_s / trained * left)} of training left "
        f"(this run: {trained} generation{'s' if trained > 1 else ''} in {span(elapsed_s)})"
    )


class Runner:
    """Runs an experiment's trials as Ray tasks, evaluates them and writes the results."""

    max_lost: int = 3
    """times a trial is resubmitted after its node (or a worker it needs) was lost"""

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
        self.pace: tuple[float, int] | None = None
        """(when, generations trained) at the first progress view: the pace is this run's"""

    def mirror_of(self, trial: str) -> bool | None:
        """Whether `trial` mirrors its folder (`mirror`; a subclass may decide per trial)."""
        return self.mirror

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
        flight = InFlight(self, remote, states, todo)
        try:
            flight.fly(width)
        finally:
            flight.release()
        failed = flight.failed
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
        trained = sum(
            r["generations"] if r["status"] == "done" else (r["generation"] or 0)
            for r in rows.values()
        )
        now = time.monotonic()
        self.pace = self.pace or (now, trained)
        left = time_left(
            now - self.pace[0],
            trained - self.pace[1],
            sum(r["generations"] for r in rows.values()) - trained,
        )
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
            + (f"; {left}" if left else "")
        )

    # ---- phase 2: evaluation ----------------------------------------------------------------
    def learner_file(self, trial: str) -> Path:
        root = self.trial_dir(trial)
        return root / ("best.pt" if self.exp.evaluation.learner == "best" else "learner.pt")

    def evaluation_scenario(self) -> PursuitConfig:
        """The scenario every trial is evaluated in: the one they trained in, with the
        default reward (one reward for every trial's returns, whatever each trained with).
        Trials that trained in different scenarios cannot share one evaluation."""
        games: list[PursuitConfig] = []
        for t in self.exp.trials():
            game = self.configs[t].env.played()
            if game not in games:
                games.append(game)
        if len(games) > 1:
            raise RuntimeError(
                "the trials train in different scenarios (besides the reward); "
                "evaluate them in separate experiments"
            )
        return games[0]

    def evaluate(self, trials: Sequence[str] | None = None) -> dict[str, dict[str, Any]]:
        """Every trial's learner (or those of `trials`) against the pools, each cached in
        OUT/evaluation/<trial>.json with the settings it was played under."""
        import ray

        self.eval_dir.mkdir(parents=True, exist_ok=True)
        from hola_ray.evaluation.scale import reference_fingerprint
        from hola_ray.evaluation.zero_shot import normalised_line, pool_fingerprints

        scenario = self.evaluation_scenario()
        settings = {
            "scenario": scenario.to_dict(),
            "episodes": self.exp.evaluation.episodes,
            "seeds": list(self.exp.evaluation.seeds),
            "cell_episodes": self.exp.evaluation.cell_episodes,
            "pools": list(self.exp.evaluation.pools),
            "format": EVALUATION_FORMAT,
            "pool_manifests": pool_fingerprints(self.exp.evaluation.pools),
            "reference": reference_fingerprint(),
        }
        results: dict[str, dict[str, Any]] = {}
        todo: list[str] = []
        trials = list(self.exp.trials() if trials is None else trials)
        for t in trials:
            cached = self.eval_dir / f"{t}.json"
            if cached.is_file():
                saved = json.loads(cached.read_text())
                if saved.get("settings") == settings:
                    results[t] = saved["pools"]
                    continue
            todo.append(t)
        if not todo:
            return {t: results[t] for t in trials}
        self.say(
            f"evaluating {len(todo)} learner(s) against {', '.join(settings['pools'])}: "
            "the pools' reference returns first"
        )
        start = time.monotonic()
        reference = ray.remote(num_cpus=1, max_retries=1)(_reference)
        refs = {p: reference.remote(p, settings, scenario) for p in settings["pools"]}
        references = ray.put({p: ray.get(r) for p, r in refs.items()})
        self.say(f"reference returns: {time.monotonic() - start:.0f} s")
        remote = ray.remote(num_cpus=1, max_retries=1)(_evaluate_trial)
        pending: dict[Any, str] = {
            remote.remote(self.learner_file(t).read_bytes(), settings, scenario, references): t
            for t in todo
        }
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            t = pending.pop(ready[0])
            results[t] = ray.get(ready[0])
            _atomic_json(self.eval_dir / f"{t}.json", {"settings": settings, "pools": results[t]})
            figures = "; ".join(
                f"{p} success {r['success']:.1%}, collision {r['collision']:.1%}"
                + (f", normalised {normalised_line(r['scale'])}" if "scale" in r else "")
                for p, r in results[t].items()
            )
            self.say(f"{t}: {figures}")
        return {t: results[t] for t in trials}

    def evaluate_open_teams(self) -> dict[str, Any]:
        """`evaluation.protocol: open-teams`: every trial's learner through contract §6.4's
        grid, in the trials' scenario (which may differ in the team and the arena only),
        each method figured over its seeds (paired where the methods share them), written
        to OUT (results.json, results.md, open-teams-<arena>.png), where the publisher
        finds them."""
        from hola_ray import homes
        from hola_ray.config.scenario import ARENAS
        from hola_ray.evaluation import open_teams
        from hola_ray.evaluation.scale import reference_fingerprint
        from hola_ray.evaluation.zero_shot import pool_fingerprints

        trials = self.exp.trials()
        evaders = {self.configs[t].env.n_evaders for t in trials}
        if len(evaders) > 1:
            raise RuntimeError(
                f"the trials chase different numbers of evaders ({sorted(evaders)}): the "
                "open-team grid plays one; evaluate them in separate experiments"
            )
        # the grid's scenario: the trials' own but for the team, the arena and the reward
        try:
            base = open_teams.grid_base([self.configs[t].env for t in trials])
        except ValueError as err:
            raise RuntimeError(f"{err}: evaluate them in separate experiments") from err
        settings = self.exp.evaluation
        groups = {m: [t for t in trials if parse_trial(t)[0] == m] for m in self.exp.methods}
        training_seeds = {m: [parse_trial(t)[1] for t in ts] for m, ts in groups.items()}
        # each cell kept in OUT/evaluation/open-teams as it is played: a resume plays the rest
        cache = open_teams.CellCache(
            self.eval_dir / "open-teams",
            {
                "learners": {t: homes.sha256(self.learner_file(t)) for t in trials},
                "scenario": base.to_dict(),
                "episodes": settings.episodes,
                "seeds": list(settings.seeds),
                "pool_manifests": pool_fingerprints(settings.pools),
                "reference": reference_fingerprint(),
                "groups": groups,
                "training_seeds": training_seeds,
                "format": EVALUATION_FORMAT,
            },
        )
        results = open_teams.run_protocol(
            {t: open_teams.learner_loader(self.learner_file(t)) for t in trials},
            list(settings.pools),
            base,
            settings.episodes,
            list(settings.seeds),
            list(settings.arenas or ARENAS),
            list(settings.modes or open_teams.MODES),
            list(settings.sizes or open_teams.SIZES),
            say=self.say,
            groups=groups,
            training_seeds=training_seeds,
            cache=cache,
        )
        _atomic_json(self.out / "results.json", results)
        written = open_teams.report(results, self.out)
        self.say(f"wrote {self.out / 'results.json'}, " + ", ".join(p.name for p in written))
        return results

    # ---- phase 3: results -------------------------------------------------------------------
    def write_results(
        self,
        per_trial: Mapping[str, Mapping[str, Any]],
        stopped_short: Mapping[str, Any] | None = None,
    ) -> dict[str, Any]:
        """results.json, results.md and figure.png of the evaluated trials (`report`)."""
        spent = {t: budget_spent(self.trial_dir(t)) for t in per_trial}
        builds = {
            t: build_label(self.configs[t].pretrain.population, parse_trial(t)[1])
            for t in per_trial
        }
        return write_results(self.exp, self.out, per_trial, spent, builds, stopped_short)

    def whole_seeds(self) -> tuple[list[int], list[str]]:
        """The seeds whose every method's trial is done, in the plan's order, and the
        trials left out (not done, or of a seed with one not done): what `--stop-short`
        evaluates, so that every method is figured over the same seeds."""
        states = self.states()
        seeds = [
            s
            for s in self.exp.seeds
            if all(states[trial_name(m, s)][0] == "done" for m in self.exp.methods)
        ]
        left = [t for t in self.exp.trials() if parse_trial(t)[1] not in seeds]
        return seeds, left

    def stop_short(self) -> dict[str, Any]:
        """The experiment ended before its plan: train nothing more, evaluate the trials of
        `whole_seeds` and write the results marked as stopped short (the trials left out
        stay as they are: a later --resume without --stop-short trains them on)."""
        if self.exp.evaluation is None or self.exp.evaluation.protocol != "zero-shot":
            raise RuntimeError(
                "--stop-short evaluates trial by trial: this experiment's evaluation is "
                f"{'none' if self.exp.evaluation is None else self.exp.evaluation.protocol}"
            )
        seeds, left = self.whole_seeds()
        if not seeds:
            raise RuntimeError(
                "--stop-short: no seed has every method's trial done; nothing to evaluate"
            )
        self.say(
            f"stopping short of the plan: {len(seeds)} of {len(self.exp.seeds)} seeds have "
            f"every method done; {len(left)} trial(s) left out"
        )
        evaluated = [trial_name(m, s) for s in seeds for m in self.exp.methods]
        per_trial = self.evaluate(evaluated)
        results = self.write_results(per_trial, {"seeds": seeds, "left_out": left})
        self.say(f"wrote {self.out / 'results.json'}, results.md and figure.png (stopped short)")
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

    def run(self) -> dict[str, Any]:
        self.train()
        if self.exp.evaluation is None:
            self.say(
                f"trained; no evaluation (evaluation: none): the trials are in {self.out}/"
                "trials, their validation curves in each metrics.csv"
            )
            return {}
        if self.exp.evaluation.protocol == "open-teams":
            return self.evaluate_open_teams()
        per_trial = self.evaluate()
        results = self.write_results(per_trial)
        self.say(f"wrote {self.out / 'results.json'}, results.md and figure.png")
        return results
