"""A generation's figures that decide nothing during training: they are played by the run's
evaluation actors while the next generation trains, and written beside the generation as
`monitors.json` (`RunDir.complete`).

- `validation`: the learner with the validation teammates (`validation.pool`), in a random
  seat, its teammates drawn per episode, the same episodes every generation; `best.pt` is
  the generation that does best here, for every method.
- `self_play`: a self-play learner as a team of its own copies (`learner_*`; best.pt's
  rule when validation is off).
- `population`: can the population pursue? each member as a team of its own copies
  (measured once per node: the caller keeps `known`), and teams of distinct members drawn
  from the population (`population_team_*`).

Each is a plain function of the run's config and the exports it needs, so an actor, the
driver (`grapher.workers: 0`) and a resumed run play the same episodes to the same figures.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from hola_ray.evaluation.metrics import TEAM, VALIDATED
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.stats import mean_and_se
from hola_ray.evaluation.teams import play
from hola_ray.methods.config import RunConfig
from hola_ray.policies.learned import MLPPolicy
from hola_ray.population.state import edge_seed

VALIDATION_SEED = 90_001
"""Validation episodes' seeds: VALIDATION_SEED + the run's seed, apart from the zero-shot
evaluation's (0, 1, 2 …) and Table II's"""

_REPORTED = tuple((m.name, m.field) for m in TEAM)
"""(metric name in metrics.csv, its field in a rollout summary)"""

_VALIDATORS: dict[tuple[str, str], list] = {}
"""(pool, scenario) → the validation teammates, loaded once per process"""


def validation_teammates(config: RunConfig) -> list:
    """The validation set's members for the run's scenario (loaded once per process;
    refused if it shares a member with an evaluation pool:
    `hola_ray.evaluation.pools.load_validation`)."""
    from hola_ray.evaluation.pools import load_validation

    key = (config.validation.pool, repr(config.env))
    if key not in _VALIDATORS:
        _VALIDATORS[key] = list(load_validation(config.validation.pool, config.env).values())
    return _VALIDATORS[key]


def validation(config: RunConfig, export: Mapping[str, Any]) -> dict[str, float]:
    """`val_*`: the learner with the validation teammates."""
    start = time.perf_counter()
    played = play(
        MLPPolicy(config.env, export),
        validation_teammates(config),
        config.env,
        config.validation.episodes,
        [VALIDATION_SEED + config.seed],
    )
    out: dict[str, float] = {}
    for name in VALIDATED:
        mean, se = mean_and_se(played[name])
        out[f"val_{name}"], out[f"val_{name}_se"] = round(mean, 4), round(se, 4)
    out["monitor_validation_s"] = round(time.perf_counter() - start, 2)
    return out


def self_play(config: RunConfig, g: int, export: Mapping[str, Any]) -> dict[str, float]:
    """`learner_*`: a self-play learner in every slot, `grapher.episodes_per_edge` episodes."""
    start = time.perf_counter()
    team = [MLPPolicy(config.env, export)] * config.env.n_pursuers
    episodes = config.grapher.episodes_per_edge
    summary = rollout(config.env, team, episodes, seed=edge_seed(config.seed, g, ())).summary()
    out: dict[str, float] = {"learner_episodes": episodes}
    for name, key in _REPORTED:
        out[f"learner_{name}"] = round(summary[key], 4)
        out[f"learner_{name}_se"] = round(summary[f"{key}_se"], 4)
    out["monitor_judge_s"] = round(time.perf_counter() - start, 2)
    return out


def population(
    config: RunConfig,
    g: int,
    exports: Mapping[int, Mapping[str, Any]],
    known: Mapping[int, Mapping[str, float]],
) -> dict[str, Any]:
    """`members_*` and `population_team_*` of the population `exports` holds (node →
    export), and under `"own"` each member's figures as a team of its copies, for the
    nodes `known` did not hold yet (the caller keeps them)."""
    start = time.perf_counter()
    nodes = sorted(exports)
    episodes, n_p = config.grapher.episodes_per_edge, config.env.n_pursuers
    new = {}
    for v in nodes:
        if v not in known:
            result = rollout(
                config.env,
                [MLPPolicy(config.env, exports[v])] * n_p,
                episodes,
                seed=edge_seed(config.seed, 0, (v,) * n_p),
            )
            new[v] = team_figures(result)
    own = [known.get(v) or new[v] for v in nodes]
    out: dict[str, Any] = {
        f"members_{k}": round(float(np.mean([f[k] for f in own])), 4)
        for k in ("success", "collision", "crash")
    }
    out["members_success_min"] = round(min(f["success"] for f in own), 4)
    rng = np.random.default_rng([config.seed, g, 3])
    teams = np.stack(
        [rng.choice(len(nodes), n_p, replace=len(nodes) < n_p) for _ in range(episodes)]
    )
    policies = [MLPPolicy(config.env, exports[v]) for v in nodes]
    mixed = rollout(
        config.env, policies, episodes, assignment=teams, seed=edge_seed(config.seed, g, ())
    )
    out |= {f"population_team_{k}": round(v, 4) for k, v in team_figures(mixed).items()}
    out["monitor_judge_s"] = round(time.perf_counter() - start, 2)
    out["own"] = {int(v): f for v, f in new.items()}
    return out


def team_figures(result) -> dict[str, float]:
    """Success, collision and the share of seats that crashed, of a rollout."""
    return {
        "success": float(result.success.mean()),
        "collision": float(result.collision.mean()),
        "crash": float(result.crashed.mean()),
    }


def monitored(figures: Mapping[str, Any], row: Mapping[str, Any], n_pursuers: int) -> str:
    """What a generation's log line says of its monitors (`figures`, now in its `row`)."""
    said = ""
    if "members_success" in figures:
        said = (
            f"members as copies success {row['members_success']:.0%} (the weakest "
            f"{row['members_success_min']:.0%}), teams of members "
            f"{row['population_team_success']:.0%}; "
        )
    if "learner_success" in figures:  # self-play: the learner as copies
        said = (
            f"as {n_pursuers} copies success {row['learner_success']:.0%}, "
            f"collision {row['learner_collision']:.0%}; "
        )
    if "val_success" in figures:
        said += (
            f"with the validation teammates success {row['val_success']:.0%}, "
            f"collision {row['val_collision']:.0%}, own crash {row['val_learner_crash']:.0%}; "
        )
    return said


class Monitoring:
    """The monitors of the generation last committed: submitted to the run's evaluation
    actors (played here with none) and collected once the next generation has trained."""

    def __init__(self, config: RunConfig, pool: Any | None):
        self.config = config
        self.pool = pool
        """the run's `EvaluatorPool`, or None: play here"""
        self.known: dict[int, dict[str, float]] = {}
        """node → its figures as a team of its copies (measured once per node)"""
        self.pending: tuple[int, list] | None = None
        """(generation, its monitors: object refs, or figures played here)"""

    def submit(
        self,
        g: int,
        learner: Mapping[str, Any] | None,
        members: Mapping[int, Mapping[str, Any]] | None,
    ) -> None:
        """Start generation g's monitors: of its learner's export (None at generation 0)
        and of the population's members (node → export; None for a self-play method)."""
        c = self.config
        calls: list[tuple] = []
        if members is not None:
            calls.append((population, c, g, dict(members), dict(self.known)))
        if learner is not None and c.strategy.trains_alone():
            calls.append((self_play, c, g, dict(learner)))
        if learner is not None and c.validation.enabled:
            calls.append((validation, c, dict(learner)))
        if self.pool is None:
            self.pending = (g, [(call, call[0](*call[1:])) for call in calls])
        else:
            self.pending = (g, [(call, self.pool.submit(*call)) for call in calls])

    def collect(self) -> tuple[int, dict[str, Any]] | None:
        """The pending generation and its figures (waiting for them), or None. A monitor
        whose actor died is played here instead: the same episodes, the same figures."""
        if self.pending is None:
            return None
        import ray
        from ray.exceptions import RayActorError

        g, parts = self.pending
        self.pending = None
        figures: dict[str, Any] = {"monitored": 1}
        for call, part in parts:
            if isinstance(part, ray.ObjectRef):
                try:
                    part = ray.get(part)
                except RayActorError:
                    part = call[0](*call[1:])
            own = part.pop("own", {})
            self.known |= {int(v): f for v, f in own.items()}
            figures |= part
        return g, figures
