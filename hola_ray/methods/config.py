"""The typed, validated configuration of one training run (docs/contract.md §5).

A run config is YAML with the sections `env`, `oracle`, `pretrain`, `population`,
`grapher` and `validation`, each registered method's own section (`fcp`, `pbt`), plus the
top-level `method`, `generations` and `seed`. The sections' dataclasses live in
`hola_ray.config` (a method's own in its module); this module puts them together with the
method that trains. Everything is checked when it is loaded, before Ray starts: a bad value
raises `ConfigError` naming the field and the allowed range, and unknown keys are
rejected.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from hola_ray.config.oracle import OracleConfig
from hola_ray.config.population import GrapherConfig, PopulationConfig
from hola_ray.config.reader import ConfigError, consume_fields, load_yaml, located, require
from hola_ray.config.run import PretrainConfig, ValidationConfig
from hola_ray.config.scenario import PursuitConfig
from hola_ray.policies.learned import export_trained

__all__ = ["METHODS", "RunConfig", "sections"]


METHODS: dict[str, Any] = {}
"""method name → the method (a `hola_ray.methods.base.Method`): the value of `method` in a
run config. Filled by `hola_ray.methods.registry`, which the package imports first."""


def sections() -> dict[str, type]:
    """The config sections the registered methods bring: section name → its dataclass."""
    return {m.section[0]: m.section[1] for m in METHODS.values() if m.section is not None}


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
        """Hyperedge size: one node per pursuer slot (the largest team, `edge_sizes`)."""
        return self.edge_sizes[-1]

    @property
    def edge_sizes(self) -> tuple[int, ...]:
        """The hyperedges' sizes: the sizes of the teams an episode is flown in (contract
        §6.2, `TeamChangeConfig.sizes`); the paper's team: (n_pursuers,)."""
        return self.env.team.sizes(self.env.n_pursuers)

    def export(self, state: Mapping[str, Any]) -> dict[str, Any]:
        """The plain-torch export (`MLPPolicy`) of an RLlib module state of this config,
        with the scenario it was trained in."""
        return export_trained(self.oracle, state, self.env)

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
