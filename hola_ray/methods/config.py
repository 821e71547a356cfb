"""The typed, validated configuration of one training run (docs/contract.md §5).

A run config is YAML with the sections `env`, `oracle`, `pretrain`, `population`,
`grapher` and `validation`, each registered method's own section (`fcp`, `pbt`), plus the
top-level `method`, `generations` and `seed`. The sections live beside what reads them
(`oracle/config.py`, `population/config.py`, a method's module); this module puts them
together. Everything is checked
when it is loaded, before Ray starts: a bad value raises `ConfigError` naming the field
and the allowed range, and unknown keys are rejected.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from hola_ray.env.config import (
    ConfigError,
    PursuitConfig,
    consume_fields,
    finite_in,
    load_yaml,
    located,
    positive_int,
    require,
)
from hola_ray.oracle.config import BUDGETS, SAMPLERS, OracleConfig
from hola_ray.population.config import GrapherConfig, PopulationConfig

__all__ = [
    "BUDGETS",
    "METHODS",
    "SAMPLERS",
    "ConfigError",
    "GrapherConfig",
    "OracleConfig",
    "PopulationConfig",
    "PretrainConfig",
    "RunConfig",
    "ValidationConfig",
]


METHODS: dict[str, Any] = {}
"""method name → the method (a `hola_ray.methods.base.Method`): the value of `method` in a
run config. Filled by `hola_ray.methods.registry`, which the package imports first."""


def sections() -> dict[str, type]:
    """The config sections the registered methods bring: section name → its dataclass."""
    return {m.section[0]: m.section[1] for m in METHODS.values() if m.section is not None}


@dataclass(frozen=True)
class PretrainConfig:
    """MEP pre-training of the initial population (paper §IV-B, pre-training phase)."""

    env_steps: int = 200_000
    """environment steps of PPO training of the initial population; with `until_success`,
    the most it may take"""
    alpha: float = 0.05
    """α: weight of the population mean policy's entropy bonus −log π̄(a|s), in [0, 1]"""
    alpha_until: int = 0
    """> 0: the population-entropy bonus applies for the first alpha_until env steps only;
    after them the members train on with α 0 (the same weights, a fresh optimizer), to
    narrow the spread the bonus keeps wide; 0: α throughout"""
    scheme: str = "self-play"
    """self-play: each member in self-play, its own copies in every seat of an episode (as
    MEP trains its population; the bonus's π̄ is over all members); mixed: the members
    drawn per seat into mixed teams (the joint scheme before it, kept for ablation)"""
    until_success: float = 0.0
    """> 0: stop once every member, as a team of its own copies, succeeds in at least this
    share of `until_episodes` episodes (and collides in at most `until_collision`),
    judged every `check_every` env steps; 0: train for `env_steps`"""
    until_collision: float = 1.0
    """the most collision of every member as a team of its own copies, with `until_success`"""
    until_episodes: int = 300
    """episodes per member at each check"""
    until_in_a_row: int = 1
    """checks in a row that must find every member competent before the build stops: the
    first check to pass is also the one its noise favoured (mep-3v2-s1 stopped when a member
    read 32 % collision on 300 episodes, then collided 39 % in its manifest's 500)"""
    check_every: int = 200_000
    """environment steps between checks"""
    population: str = "none"
    """a shipped population (pools/populations/<name>, or a folder with its manifest) taken
    as generation 0 instead of pre-training; `{seed}` in the name is the run's seed
    (`{seed%N}` modulo N) and `{kind}` the kind of population its method builds
    (`mep-3v1-s{seed}`, `{kind}-3v2-s{seed%3}`; `hola_ray.population.shipped`); none:
    pre-train. A method
    without a population (self-play) takes only its learner's start from it
    (`learner_start: member`)"""
    learner_start: str = "random"
    """the learner's weights at generation 1: random (a fresh network), or member: a copy of
    the generation-0 member the population prefers most (the highest η, preference
    centrality; the lowest node on a tie), as the paper's Oracle maps a strategy j to
    BR(j, G_j) and G_0's most preferred member is the natural j at generation 1; for
    self-play, the most preferred member of the shipped `population` (FCP's: a self-play
    checkpoint; with `population: none`, random); PBT, whose generations train its agents
    in turn, ignores it"""

    start_agent: str = "none"
    """a shipped population (as `population` names one) whose last node every method's
    learner starts from at generation 1, in place of `learner_start`: a neutral start, the
    same for every method of a seed and in no population a run trains beside, nor in a
    pool (checked when the run starts); for an FCP-built start, its last agent's end
    checkpoint. PBT, whose generations train its agents in turn, begins every agent as a
    copy of it (with `population: none`); none: off"""

    def validate(self) -> None:
        positive_int("pretrain", self, "env_steps", maximum=10**11)
        finite_in("pretrain", self, "alpha", 0.0, 1.0, "in [0, 1]")
        ok = isinstance(self.alpha_until, int) and not isinstance(self.alpha_until, bool)
        require(
            ok and 0 <= self.alpha_until <= 10**11,
            "pretrain.alpha_until",
            "an integer >= 0 (0: the bonus throughout)",
            self.alpha_until,
        )
        require(
            self.scheme in PRETRAIN_SCHEMES,
            "pretrain.scheme",
            " or ".join(PRETRAIN_SCHEMES),
            self.scheme,
        )
        finite_in("pretrain", self, "until_success", 0.0, 1.0, "in [0, 1] (0: off)")
        finite_in("pretrain", self, "until_collision", 0.0, 1.0, "in [0, 1]")
        positive_int("pretrain", self, "until_episodes", maximum=10**6)
        positive_int("pretrain", self, "until_in_a_row", maximum=1000)
        positive_int("pretrain", self, "check_every", maximum=10**11)
        require(
            isinstance(self.population, str) and bool(self.population),
            "pretrain.population",
            "none or a shipped population's name or folder",
            self.population,
        )
        require(
            isinstance(self.start_agent, str) and bool(self.start_agent),
            "pretrain.start_agent",
            "none or a shipped population's name or folder",
            self.start_agent,
        )
        require(
            self.learner_start in LEARNER_STARTS,
            "pretrain.learner_start",
            " or ".join(LEARNER_STARTS),
            self.learner_start,
        )

    @property
    def shipped(self) -> bool:
        """Whether generation 0 is a shipped population."""
        return self.population != "none"

    @property
    def until(self) -> bool:
        """Whether pre-training stops at competence (else after `env_steps`)."""
        return self.until_success > 0


LEARNER_STARTS = ("random", "member")
"""`pretrain.learner_start`: the learner's weights at generation 1"""

PRETRAIN_SCHEMES = ("self-play", "mixed")
"""`pretrain.scheme`: how MEP's members share the episodes"""


EVALUATION_POOLS = ("hot", "het")
"""the zero-shot evaluation's pools: never a run's validation teammates"""


@dataclass(frozen=True)
class ValidationConfig:
    """Validation teammates (the held-out protocol of jax-aht): after every generation the
    learner plays with teammates drawn from a set disjoint from the evaluation pools, built
    only from what training may see; every method keeps as `best.pt` the generation that
    does best there (highest success, then lowest collision)."""

    pool: str = "validation"
    """the committed validation set (`pools/validation`, `python -m hola_ray pools show
    --pool validation`), a folder holding such a manifest, or none (best.pt then follows
    each method's own judging)"""
    episodes: int = 96
    """episodes per validation: the learner in a random seat, teammates drawn per episode"""

    def validate(self) -> None:
        positive_int("validation", self, "episodes", maximum=10**6)
        ok = isinstance(self.pool, str) and self.pool not in EVALUATION_POOLS and self.pool
        require(
            bool(ok),
            "validation.pool",
            "validation, none or a folder with a pool manifest; never an evaluation pool "
            f"({', '.join(EVALUATION_POOLS)})",
            self.pool,
        )

    @property
    def enabled(self) -> bool:
        return self.pool != "none"


@dataclass(frozen=True)
class RunConfig:
    """One HOLA-Drone training run: method, budget and every sub-config."""

    method: str = "hola"
    """hola (φ from the inverse Myerson value), hola_r (the inverse mean reward), uniform,
    sp (self-play), fcp, mep or pbt: see `hola_ray.methods.registry.METHODS`"""
    generations: int = 10
    """open-ended generations after pre-training"""
    seed: int = 0
    """run seed: network initialisation, sampling, evaluation episodes"""
    env: PursuitConfig = field(default_factory=PursuitConfig)
    """the pursuit scenario"""
    oracle: OracleConfig = field(default_factory=OracleConfig)
    """the PPO Oracle"""
    pretrain: PretrainConfig = field(default_factory=PretrainConfig)
    """MEP pre-training"""
    population: PopulationConfig = field(default_factory=PopulationConfig)
    """population and acceptance"""
    grapher: GrapherConfig = field(default_factory=GrapherConfig)
    """hyperedge evaluation"""
    validation: ValidationConfig = field(default_factory=ValidationConfig)
    """validation teammates: which generation every method keeps as best.pt"""
    sections: Mapping[str, Any] = field(default_factory=dict)
    """the registered methods' own sections (fcp, pbt), each read as `config.<name>`; a
    section left out takes its defaults"""

    def __post_init__(self) -> None:
        require(
            self.method in METHODS, "method", f"one of {', '.join(sorted(METHODS))}", self.method
        )
        for name, most in (("generations", 10**6), ("seed", 2**32 - 1)):
            value = getattr(self, name)
            ok = isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= most
            allowed = "an integer >= 0" if not ok and value is not None and _low(value) else None
            require(ok, name, allowed or f"an integer in [0, {most:,}]", value)
        known = sections()
        unknown = sorted(set(self.sections) - set(known))
        if unknown:
            raise ConfigError(f"unknown section(s) {', '.join(unknown)}", unknown[0])
        object.__setattr__(
            self, "sections", {k: self.sections.get(k) or cls() for k, cls in known.items()}
        )
        self.oracle.validate()
        self.pretrain.validate()
        self.population.validate(self.l)
        self.grapher.validate()
        for section in self.sections.values():
            section.validate()
        self.validation.validate()
        self.strategy.validate(self)

    def __getattr__(self, name: str) -> Any:
        """A method's own section: `config.fcp`, `config.pbt`."""
        sections = self.__dict__.get("sections") or {}
        if name in sections:
            return sections[name]
        raise AttributeError(f"{type(self).__name__} has no field or section {name!r}")

    @property
    def l(self) -> int:  # noqa: E743 - the paper's l
        """Hyperedge size: one node per pursuer slot."""
        return self.env.n_pursuers

    def export(self, state: Mapping[str, Any]) -> dict[str, Any]:
        """The plain-torch export (`MLPPolicy`) of an RLlib module state of this config,
        with the scenario it was trained in."""
        return self.oracle.export(state, self.env)

    def layout(self) -> dict[str, Any]:
        """What a partner must share with this run to be seated in it: the scenario's size,
        the observation, the network, the action distribution and the proximity features
        (a shipped population is refused unless it has the same, `population.shipped`), as
        plain JSON values."""
        layout = {
            "n_pursuers": self.env.n_pursuers,
            "n_evaders": self.env.n_evaders,
            "obs_dim": self.env.obs_dim,
            "hidden": list(self.oracle.hidden),
            "action_dist": self.oracle.action_dist,
            "features": self.oracle.model_features(self.env),
        }
        return json.loads(json.dumps(layout))

    def generation_zero_key(self) -> str | None:
        """What generation 0 (the pre-trained population and G_0) depends on, as a string:
        two runs with the same key build the same G_0 on one machine, so one may adopt the
        other's (`Trainer(adopt_from=…)`). None for methods whose population is not MEP's
        (self-play, FCP, PBT)."""
        if not self.strategy.origin.shared:
            return None
        oracle = {
            k: v
            for k, v in dataclasses.asdict(self.oracle).items()
            if k not in ("env_steps", "budget", "gpus_per_learner")
        }
        oracle["hidden"] = list(self.oracle.hidden)
        return json.dumps(
            {
                "seed": self.seed,
                "env": self.env.to_dict(),
                "oracle": oracle,
                "pretrain": dataclasses.asdict(self.pretrain),
                "initial_size": self.population.initial_size,
                "episodes_per_edge": self.grapher.episodes_per_edge,
            },
            sort_keys=True,
        )

    @property
    def strategy(self) -> Any:
        """The method this run trains with (its registered `hola_ray.methods.base.Method`)."""
        return METHODS[self.method]

    # ---- YAML ---------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunConfig:
        """Build from a plain mapping (YAML); unknown keys are an error."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"a run config must be a mapping, got {type(data).__name__}")
        known = sections()
        allowed = {f.name for f in dataclasses.fields(cls)} - {"sections"} | set(known)
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise ConfigError(
                f"unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed))}",
                unknown[0],
            )
        kwargs = _fields(cls, {k: v for k, v in data.items() if k not in known}, "")
        subs: dict[str, type] = {
            "oracle": OracleConfig,
            "pretrain": PretrainConfig,
            "population": PopulationConfig,
            "grapher": GrapherConfig,
            "validation": ValidationConfig,
        }
        for name, sub in subs.items():
            if name in kwargs:
                kwargs[name] = _section(sub, kwargs[name], name)
        kwargs["sections"] = {
            name: _section(sub, data[name], name) for name, sub in known.items() if name in data
        }
        if "env" in kwargs:
            try:
                kwargs["env"] = PursuitConfig.from_dict(kwargs["env"] or {})
            except ConfigError as err:
                raise err.within("env") from None
        return cls(**kwargs)

    @classmethod
    def from_yaml(cls, path: str | Path) -> RunConfig:
        """Load a run config file. Errors are one line naming the file, the line and the
        field; an empty file is an error; a field the file leaves out takes its default
        here (the paper's values, see each field)."""
        data = load_yaml(path)
        if data is None:
            raise ConfigError(f"{path} is empty: a run config needs at least its method")
        try:
            return cls.from_dict(data)
        except ConfigError as err:
            raise located(err, path) from None

    def to_dict(self) -> dict[str, Any]:
        """A plain, YAML-safe mapping that `from_dict` reads back to an equal config."""
        out: dict[str, Any] = {
            "method": self.method,
            "generations": self.generations,
            "seed": self.seed,
            "env": self.env.to_dict(),
        }
        for name in ("oracle", "pretrain", "population", "grapher"):
            out[name] = _plain(getattr(self, name))
        for name, section in self.sections.items():
            out[name] = _plain(section)
        out["validation"] = _plain(self.validation)
        return out

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


def _low(value: Any) -> bool:
    """A count below its range (rather than above it or not a number)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and value < 0


def _plain(section: Any) -> dict[str, Any]:
    """A section dataclass as YAML-safe values (tuples as lists)."""
    return {
        k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(section).items()
    }


def _section(cls: type, data: Any, name: str) -> Any:
    """The section dataclass `cls` from its mapping."""
    return cls(**_fields(cls, data, f"{name}."))


def _fields(cls: type, data: Any, prefix: str) -> dict[str, Any]:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{prefix.rstrip('.') or 'config'} must be a mapping, got {data!r}")
    return consume_fields(cls, data, prefix)
