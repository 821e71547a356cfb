"""An experiment config, validated: one run config per trial (method × seed), and the
evaluation's settings. The format is in `hola_ray.experiment`'s doc."""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hola_ray.config.reader import (
    ConfigError,
    checked,
    consume_fields,
    load_yaml,
    located,
    positive_int,
    require,
)
from hola_ray.homes import ROOT
from hola_ray.methods.config import METHODS, RunConfig

CONFIG_NAME = "experiment.yaml"


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
    protocol: str = "zero-shot"
    """zero-shot: the paper's evaluation in the trials' own scenario; open-teams: contract
    §6.4's grid (`hola_ray.evaluation.open_teams`), every method against every other"""
    arenas: tuple[str, ...] = ()
    """open-teams: the arenas (empty: all four)"""
    modes: tuple[str, ...] = ()
    """open-teams: zero-shot, open (empty: both)"""
    sizes: tuple[int, ...] = ()
    """open-teams: the team sizes (empty: 2 to 5)"""


@dataclass(frozen=True)
class Experiment:
    """A validated experiment config: one run config per trial, and the evaluation."""

    base: str
    methods: dict[str, dict[str, Any]]
    seeds: tuple[int, ...]
    overrides: dict[str, Any] = field(default_factory=dict)
    parallel: int = 0
    evaluation: EvaluationSettings | None = field(default_factory=EvaluationSettings)
    """None (`evaluation: none`): trials are trained and nothing else, a pilot that sizes a
    design on the validation teammates and never plays a pool"""
    source: Path | None = None

    @classmethod
    def from_yaml(cls, path: str | Path) -> Experiment:
        """Read and check an experiment config, and every trial's run config, before Ray
        starts: each error is one line naming the file, the line (when the file holds
        the field) and the field."""
        path = Path(path)
        if not path.is_file():
            raise ConfigError(f"experiment config {path} does not exist")
        try:
            return cls.from_dict(load_yaml(path), source=path)
        except ConfigError as err:
            raise located(err, path) from None

    @classmethod
    def from_dict(cls, raw: Any, source: Path | None = None) -> Experiment:
        if not isinstance(raw, Mapping):
            raise ConfigError(f"an experiment config must be a mapping, got {raw!r}")
        allowed = {"base", "overrides", "methods", "seeds", "parallel", "evaluation"}
        unknown = sorted(set(raw) - allowed)
        if unknown:
            raise ConfigError(f"unknown key(s) {unknown}; allowed: {sorted(allowed)}", unknown[0])
        for key in ("base", "methods", "seeds"):
            if key not in raw:
                raise ConfigError(f"`{key}` is required")
        base = checked(str, raw["base"], "base")
        methods = raw["methods"]
        if isinstance(methods, list):
            methods = dict.fromkeys(methods)
        if not isinstance(methods, Mapping) or not methods:
            raise ConfigError("methods must be a non-empty mapping method → overrides", "methods")
        for name, over in methods.items():
            if not isinstance(name, str) or "-s" in name or not name.replace("_", "").isalnum():
                raise ConfigError(
                    f"{name!r}: a method or variant name is letters, digits and _ only", "methods"
                )
            if over is not None and not isinstance(over, Mapping):
                raise ConfigError(f"methods.{name} must be a mapping of overrides, got {over!r}")
            method = (over or {}).get("method", name)
            if method not in METHODS:
                raise ConfigError(
                    f"{name}: unknown method {method!r}; known: {sorted(METHODS)} (a variant "
                    "of a method names it in its overrides: `hola_long: {method: hola, …}`)",
                    f"methods.{name}",
                )
        seeds = checked(tuple[int, ...], raw["seeds"], "seeds")
        ok = len(seeds) > 0 and min(seeds) >= 0 and len(set(seeds)) == len(seeds)
        require(ok, "seeds", "a non-empty list of distinct integers >= 0", raw["seeds"])
        overrides = raw.get("overrides") or {}
        if not isinstance(overrides, Mapping):
            raise ConfigError(f"overrides must be a mapping, got {overrides!r}", "overrides")
        parallel = checked(int, raw.get("parallel", 0), "parallel")
        ok = 0 <= parallel <= 100_000
        require(ok, "parallel", "an integer in [0, 100,000] (0: every trial at once)", parallel)
        exp = cls(
            base=base,
            methods={m: dict(o or {}) for m, o in methods.items()},
            seeds=tuple(seeds),
            overrides=dict(overrides),
            parallel=parallel,
            evaluation=_evaluation(raw.get("evaluation"), set(methods)),
            source=source,
        )
        for name in exp.trials():  # every trial's run config is valid before Ray starts
            try:
                exp.run_config(name)
            except ConfigError as err:
                raise ConfigError(f"trial {name}: {err}") from err
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
        more = self.evaluation.pairs if self.evaluation is not None else ()
        return out + [p for p in more if p not in out]

    def trials(self) -> list[str]:
        """Trial names, seed by seed (`<method>-s<seed>`): an experiment stopped part way
        through holds whole seeds, every method's trial of each, which is what a paired
        comparison reads."""
        return [trial_name(m, s) for s in self.seeds for m in self.methods]

    def run_config(self, trial: str) -> RunConfig:
        method, seed = parse_trial(trial)
        base = load_yaml(self.base_path()) or {}
        merged = deep_merge(deep_merge(base, self.overrides), self.methods[method])
        merged.update(method=self.methods[method].get("method", method), seed=seed)
        return RunConfig.from_dict(merged)


def _evaluation(raw: Any, methods: set[str]) -> EvaluationSettings | None:
    """The `evaluation` section, checked field by field; `none`: no evaluation."""
    if raw is None:
        return EvaluationSettings()
    if raw == "none":
        return None
    if not isinstance(raw, Mapping):
        raise ConfigError(f"evaluation must be a mapping or none, got {raw!r}", "evaluation")
    settings = EvaluationSettings(**consume_fields(EvaluationSettings, raw, "evaluation."))
    positive_int("evaluation", settings, "episodes", "cell_episodes", maximum=10**6)
    ok = len(settings.seeds) > 0 and min(settings.seeds) >= 0
    require(ok, "evaluation.seeds", "a non-empty list of integers >= 0", list(settings.seeds))
    require(len(settings.pools) > 0, "evaluation.pools", "a non-empty list", settings.pools)
    require(
        settings.learner in ("final", "best"),
        "evaluation.learner",
        "final or best",
        settings.learner,
    )
    ok = all(set(pair) <= methods for pair in settings.pairs)
    require(ok, "evaluation.pairs", "[A, B] pairs of the experiment's methods", settings.pairs)
    protocols = ("zero-shot", "open-teams")
    require(
        settings.protocol in protocols,
        "evaluation.protocol",
        " or ".join(protocols),
        settings.protocol,
    )
    from hola_ray.config.scenario import ARENAS
    from hola_ray.evaluation.open_teams import MODES, SIZES

    for key, known in (("arenas", ARENAS), ("modes", MODES), ("sizes", SIZES)):
        given = getattr(settings, key)
        ok = all(x in known for x in given)
        require(ok, f"evaluation.{key}", f"any of {list(known)}", list(given))
    return settings


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
