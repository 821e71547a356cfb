"""The typed, validated configuration of one training run (SPEC §5).

A run config is YAML with the sections `env`, `oracle`, `pretrain`, `population` and
`grapher` plus the top-level `method`, `generations` and `seed`. Everything is checked
when it is loaded, before Ray starts: a bad value raises `ConfigError` naming the field
and the allowed range, and unknown keys are rejected.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from hola_ray.env.config import (
    ConfigError,
    PursuitConfig,
    consume_fields,
    load_yaml,
    located,
    require,
)
from hola_ray.env.layout import ObsLayout
from hola_ray.policies.learned import DISTRIBUTIONS, export_from_rllib

SAMPLERS = ("batched", "pettingzoo")
BUDGETS = ("env_steps", "learner_samples")
"""oracle.sampler: how the Oracle's env runners sample (OracleConfig.sampler)."""


POPULATIONS = ("mep", "fcp", "pbt", "none")
"""Method.population: how the partner population is built."""
PARTNER_DRAWS = ("myerson", "mean_reward", "uniform", "rank")
"""Method.phi_kind: how the Oracle draws partners from the population."""


@dataclass(frozen=True)
class Method:
    """A training method as a strategy over the one trainer (SPEC §5): how the partner
    population is built, how the Oracle draws partners from it, who joins it. Adding a
    method is adding one entry to METHODS (and, for a new way to build or draw, one branch
    where `population` or `phi_kind` is read: `Trainer._pretrain`, `Population.phi`)."""

    name: str
    """the value of `method` in a run config"""
    population: str
    """mep: pre-trained jointly with the population-entropy bonus (MEP, Zhao 2023);
    fcp: self-play agents of `fcp.agents` seeds, each at the start, middle and end of its
    training (FCP, Strouse 2021); pbt: `population.initial_size` PPO agents trained jointly
    with each other (the MEP pre-training without its entropy bonus), then each trained in
    turn (PBT); none: no partners (self-play)"""
    phi_kind: str | None
    """myerson / mean_reward: φ = the shifted inverse of that node value (SPEC §4);
    uniform: every member equally; rank: p ∝ rank^β, rank 1 for the partner the learner
    scores best with (MEP's prioritised sampling, rank(1/return)^β); None: self-play"""
    joins: bool
    """the learner joins the population when its η rank is within the top m (pbt: it
    replaces the agent it was trained from); False: the population stays fixed and the
    learner is its best response"""
    description: str
    """one line for help texts"""

    @property
    def self_play(self) -> bool:
        """Every seat plays the learner: no population, no pre-training, no Grapher; the
        learner is judged by its own team's rollout."""
        return self.population == "none"


METHODS = {
    m.name: m
    for m in (
        Method(
            "hola",
            "mep",
            "myerson",
            True,
            "HOLA-Drone: partners drawn by the inverse Myerson value",
        ),
        Method(
            "hola_r",
            "mep",
            "mean_reward",
            True,
            "HOLA-Drone_R: partners by the inverse mean reward",
        ),
        Method(
            "uniform",
            "mep",
            "uniform",
            True,
            "HOLA-Drone with uniform partners: the control for what φ adds",
        ),
        Method("sp", "none", None, False, "self-play: one trained module in every seat"),
        Method(
            "fcp",
            "fcp",
            "uniform",
            False,
            "FCP: a best response to frozen self-play checkpoints, drawn uniformly",
        ),
        Method(
            "mep",
            "mep",
            "rank",
            False,
            "MEP: a best response to the MEP population, prioritised by rank(1/return)^β",
        ),
        Method(
            "pbt",
            "pbt",
            "uniform",
            True,
            "PBT: agents trained in turn with the others, exploit and explore (lr, entropy)",
        ),
    )
}
"""The methods a run config may name."""


def _positive_int(section: str, obj: Any, *names: str, minimum: int = 1) -> None:
    for name in names:
        value = getattr(obj, name)
        ok = isinstance(value, int) and not isinstance(value, bool) and value >= minimum
        require(ok, f"{section}.{name}", f"an integer >= {minimum}", value)


def _finite(section: str, obj: Any, name: str, low: float, high: float, allowed: str) -> None:
    value = getattr(obj, name)
    ok = isinstance(value, int | float) and math.isfinite(value) and low <= value <= high
    require(ok, f"{section}.{name}", allowed, value)


@dataclass(frozen=True)
class OracleConfig:
    """The multi-agent PPO that trains the learner each generation (paper Appendix)."""

    env_steps: int = 1_000_000
    """the Oracle's budget for one generation, counted as `budget` says"""
    train_batch: int = 1024
    """the size of one PPO update's batch, counted as `budget` says"""
    budget: str = "env_steps"
    """what `env_steps` and `train_batch` count: env_steps (environment steps, the paper's
    budget: self-play's learner then learns from every seat of a step, a single learner from
    one, a third of the data at 3 pursuers) or learner_samples (the trained module's own
    transitions, one per seat it plays per step: every method's learner consumes the same
    number and takes the same number of gradient steps; a self-play batch then spans a third
    of the environment steps)"""
    minibatch: int = 256
    """SGD minibatch size (agent steps of the learner)"""
    epochs: int = 20
    """PPO epochs over each train batch"""
    lr: float = 3e-4
    """Adam learning rate"""
    gamma: float = 0.99
    """reward discount"""
    gae_lambda: float = 0.95
    """GAE λ"""
    vf_coef: float = 1.0
    """value-loss coefficient"""
    entropy_coef: float = 0.01
    """entropy-bonus coefficient"""
    action_dist: str = "beta"
    """the policy's action distribution: beta (bounded, hola_ray/oracle/distribution.py) or
    gaussian (RLlib's default; unbounded, its samples clip at the Box)"""
    proximity_length: float = 0.15
    """ρ, metres: the networks also read exp(−d/ρ) of the obstacle and teammate distances
    (hola_ray/policies/learned.py, proximity_features); 0 = the raw observation only"""
    clip: float = 0.2
    """PPO clip parameter"""
    kl_coef: float = 0.0
    """initial coefficient of RLlib's adaptive KL penalty (RLlib's default 0.2); 0 = off,
    the clipped objective alone, as in the PPO paper and CleanRL"""
    vf_clip: float = 1e6
    """squared value errors above this give no gradient (RLlib's vf_clip_param, default
    10: with capture and collision rewards of ±10 it silenced most of the critic's errors)"""
    grad_clip: float = 0.5
    """global gradient-norm clip (CleanRL's and SB3's 0.5); 0 = none (RLlib's default)"""
    hidden: tuple[int, ...] = (256, 256)
    """hidden layer widths of the actor and the critic (tanh)"""
    env_runners: int = 1
    """RLlib env runner actors; on 2 CPUs one runner with many vector envs samples fastest"""
    envs_per_runner: int = 16
    """vectorised environments in each env runner"""
    gpus_per_learner: float = 0.0
    """GPUs for the PPO learner (RLlib's num_gpus_per_learner); 0 = the learner runs on the
    CPU in the driver. A GPU speeds up the paper's 256×256 update; sampling stays on CPUs"""
    horizon_terminates: bool = False
    """true reproduces RLlib's own marking, for ablations only: an episode cut at the
    horizon counts as terminated and nothing bootstraps V(s_T) (the default: truncated,
    hola_ray/env/horizon.py)"""
    sampler: str = "batched"
    """how env runners sample: batched (hola_ray/oracle/batched_runner.py: every vector env
    in one compiled step, one forward pass per module, episodes built in bulk) or
    pettingzoo (RLlib's MultiAgentEnvRunner over the PettingZoo env, step by step)"""

    def validate(self) -> None:
        s = "oracle"
        _positive_int(s, self, "env_steps", "train_batch", "minibatch", "epochs")
        _positive_int(s, self, "envs_per_runner")
        _positive_int(s, self, "env_runners", minimum=0)
        require(
            self.minibatch <= self.train_batch,
            "oracle.minibatch",
            f"<= oracle.train_batch ({self.train_batch})",
            self.minibatch,
        )
        _finite(s, self, "lr", 1e-8, 1.0, "in [1e-8, 1]")
        _finite(s, self, "gamma", 0.0, 1.0, "in [0, 1]")
        _finite(s, self, "gae_lambda", 0.0, 1.0, "in [0, 1]")
        _finite(s, self, "vf_coef", 0.0, 1e3, "in [0, 1000]")
        _finite(s, self, "entropy_coef", 0.0, 1.0, "in [0, 1]")
        _finite(s, self, "clip", 1e-3, 1.0, "in [0.001, 1]")
        _finite(s, self, "kl_coef", 0.0, 10.0, "in [0, 10]")
        _finite(s, self, "vf_clip", 1e-3, 1e12, "in [0.001, 1e12]")
        _finite(s, self, "grad_clip", 0.0, 1e6, "in [0, 1e6] (0 = none)")
        _finite(s, self, "proximity_length", 0.0, 10.0, "in [0, 10] (0 = off)")
        _finite(s, self, "gpus_per_learner", 0.0, 64.0, "in [0, 64] (0 = CPU)")
        require(
            self.budget in BUDGETS, "oracle.budget", f"one of {', '.join(BUDGETS)}", self.budget
        )
        require(
            isinstance(self.horizon_terminates, bool),
            "oracle.horizon_terminates",
            "true or false",
            self.horizon_terminates,
        )
        require(
            self.sampler in SAMPLERS,
            "oracle.sampler",
            f"one of {', '.join(SAMPLERS)}",
            self.sampler,
        )
        require(
            self.action_dist in DISTRIBUTIONS,
            "oracle.action_dist",
            f"one of {', '.join(DISTRIBUTIONS)}",
            self.action_dist,
        )
        ok = len(self.hidden) >= 1 and all(isinstance(h, int) and h >= 1 for h in self.hidden)
        require(ok, "oracle.hidden", "a non-empty list of positive layer widths", self.hidden)


@dataclass(frozen=True)
class PretrainConfig:
    """MEP pre-training of the initial population (paper §IV-B, pre-training phase)."""

    env_steps: int = 200_000
    """environment steps of joint PPO training of the initial population"""
    alpha: float = 0.05
    """α: weight of the population mean policy's entropy bonus −log π̄(a|s), in [0, 1]"""

    def validate(self) -> None:
        _positive_int("pretrain", self, "env_steps")
        _finite("pretrain", self, "alpha", 0.0, 1.0, "in [0, 1]")


@dataclass(frozen=True)
class PopulationConfig:
    """The population that the HyFoG describes (SPEC §4–5)."""

    max_size: int = 10
    """hypergraph size: most members in the population"""
    initial_size: int = 4
    """members pre-trained with MEP to build G_0"""
    top_m: int = 3
    """the learner joins when its η rank is within the top m (the approximate oracle)"""
    phi_shift: float = 0.1
    """φ = normalised 1/(x − x_min + shift·(x_max − x_min)), x the node values"""
    rank_beta: float = 3.0
    """β of MEP's prioritised partner sampling p ∝ rank^β (method mep)"""

    def validate(self, l: int) -> None:  # noqa: E741 - the paper's l
        s = "population"
        _positive_int(s, self, "max_size", "initial_size", "top_m")
        require(
            self.max_size >= l,
            "population.max_size (the hypergraph size)",
            f">= l = env.n_pursuers = {l}",
            self.max_size,
        )
        require(
            l <= self.initial_size <= self.max_size,
            "population.initial_size",
            f"in [l = {l}, population.max_size = {self.max_size}]",
            self.initial_size,
        )
        require(
            self.top_m <= self.max_size,
            "population.top_m",
            f"<= population.max_size ({self.max_size})",
            self.top_m,
        )
        _finite(s, self, "phi_shift", 1e-6, 10.0, "in [1e-6, 10]")
        _finite(s, self, "rank_beta", 0.0, 100.0, "in [0, 100]")


@dataclass(frozen=True)
class PBTConfig:
    """Population-based training's exploit and explore (method pbt; Jaderberg et al. 2017
    as Carroll et al. 2019 use it). Each generation trains one agent, in turn, with
    partners drawn uniformly from the other agents; it then replaces its earlier self."""

    quantile: float = 0.25
    """an agent scoring in the bottom quantile copies one from the top quantile (exploit)"""
    perturb: tuple[float, ...] = (0.8, 1.2)
    """and multiplies that agent's lr and entropy coefficient by a factor drawn from these
    (explore)"""

    def validate(self) -> None:
        _finite("pbt", self, "quantile", 0.01, 0.5, "in [0.01, 0.5]")
        ok = len(self.perturb) >= 1 and all(
            isinstance(f, int | float) and 0 < f < 10 for f in self.perturb
        )
        require(ok, "pbt.perturb", "a non-empty list of factors in (0, 10)", self.perturb)


@dataclass(frozen=True)
class FCPConfig:
    """Fictitious Co-Play's partner population (method fcp; Strouse et al. 2021)."""

    agents: int = 2
    """self-play agents, each from its own seed; each gives 3 members (its start, middle
    and end checkpoints), so population.max_size must hold 3 · agents"""
    env_steps: int = 100_000
    """environment steps of each agent's self-play training"""

    def validate(self) -> None:
        _positive_int("fcp", self, "agents", "env_steps")


@dataclass(frozen=True)
class GrapherConfig:
    """How the Grapher weighs hyperedges by simulation."""

    episodes_per_edge: int = 32
    """evaluation episodes behind each hyperedge weight"""
    edges_per_learner: int = 0
    """(l − 1)-sets of members sampled for the learner's hyperedges; 0 = every one"""
    workers: int = 2
    """hyperedge evaluations in flight at once (member actors busy at a time)"""

    def validate(self) -> None:
        _positive_int("grapher", self, "episodes_per_edge", "workers")
        _positive_int("grapher", self, "edges_per_learner", minimum=0)


EVALUATION_POOLS = ("hot", "het")
"""the zero-shot evaluation's pools: never a run's validation teammates"""


@dataclass(frozen=True)
class ValidationConfig:
    """Validation teammates (the held-out protocol of jax-aht): after every generation the
    learner plays with teammates drawn from a set disjoint from the evaluation pools, built
    only from what training may see; every method keeps as `best.pt` the generation that
    does best there (highest success, then lowest collision)."""

    pool: str = "validation"
    """the committed validation set (`pools/validation`, `python -m hola_ray.pools show
    --pool validation`), a folder holding such a manifest, or none (best.pt then follows
    each method's own judging)"""
    episodes: int = 96
    """episodes per validation: the learner in a random seat, teammates drawn per episode"""

    def validate(self) -> None:
        _positive_int("validation", self, "episodes")
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
    sp (self-play), fcp or mep: see METHODS"""
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
    fcp: FCPConfig = field(default_factory=FCPConfig)
    """FCP's self-play partners (method fcp only)"""
    pbt: PBTConfig = field(default_factory=PBTConfig)
    """PBT's exploit and explore (method pbt only)"""
    validation: ValidationConfig = field(default_factory=ValidationConfig)
    """validation teammates: which generation every method keeps as best.pt"""

    def __post_init__(self) -> None:
        require(
            self.method in METHODS, "method", f"one of {', '.join(sorted(METHODS))}", self.method
        )
        for name in ("generations", "seed"):
            value = getattr(self, name)
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
            require(ok, name, "an integer >= 0", value)
        self.oracle.validate()
        self.pretrain.validate()
        self.population.validate(self.l)
        self.grapher.validate()
        self.fcp.validate()
        self.pbt.validate()
        self.validation.validate()
        if self.strategy.population == "fcp":
            members = 3 * self.fcp.agents
            require(
                self.l <= members <= self.population.max_size,
                "fcp.agents",
                f"such that l = {self.l} <= 3 · fcp.agents <= population.max_size "
                f"({self.population.max_size})",
                self.fcp.agents,
            )

    @property
    def l(self) -> int:  # noqa: E743 - the paper's l
        """Hyperedge size: one node per pursuer slot."""
        return self.env.n_pursuers

    @property
    def model_features(self) -> dict[str, Any] | None:
        """The learned policies' proximity features ({"indices", "gain"}), or None."""
        if self.oracle.proximity_length == 0:
            return None
        return {
            "indices": ObsLayout.from_config(self.env).proximity,
            "gain": self.env.obs_distance_scale / self.oracle.proximity_length,
        }

    def export(self, state: Mapping[str, Any]) -> dict[str, Any]:
        """The plain-torch export (`MLPPolicy`) of an RLlib module state of this config,
        with the scenario it was trained in."""
        export = export_from_rllib(
            state, activation="tanh", dist=self.oracle.action_dist, features=self.model_features
        )
        return export | {"scenario": self.env.to_dict()}

    def generation_zero_key(self) -> str | None:
        """What generation 0 (the pre-trained population and G_0) depends on, as a string:
        two runs with the same key build the same G_0 on one machine, so one may adopt the
        other's (`Trainer(adopt_from=…)`). None for methods whose population is not MEP's
        (self-play, FCP, PBT)."""
        if self.strategy.population != "mep":
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
    def strategy(self) -> Method:
        """The method this run trains with."""
        return METHODS[self.method]

    @property
    def phi_kind(self) -> str:
        """How the Oracle draws partners (`PARTNER_DRAWS`); self-play has none."""
        return self.strategy.phi_kind or "uniform"

    # ---- YAML ---------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunConfig:
        """Build from a plain mapping (YAML); unknown keys are an error."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"a run config must be a mapping, got {type(data).__name__}")
        kwargs = _fields(cls, data, "")
        for name, sub in (
            ("oracle", OracleConfig),
            ("pretrain", PretrainConfig),
            ("population", PopulationConfig),
            ("grapher", GrapherConfig),
            ("fcp", FCPConfig),
            ("pbt", PBTConfig),
            ("validation", ValidationConfig),
        ):
            if name in kwargs:
                kwargs[name] = sub(**_fields(sub, kwargs[name], f"{name}."))
        if "env" in kwargs:
            try:
                kwargs["env"] = PursuitConfig.from_dict(kwargs["env"] or {})
            except ConfigError as err:
                raise err.within("env") from None
        if "oracle" in kwargs:
            hidden = kwargs["oracle"].hidden
            if isinstance(hidden, list | tuple):
                kwargs["oracle"] = dataclasses.replace(kwargs["oracle"], hidden=tuple(hidden))
        if "pbt" in kwargs and isinstance(kwargs["pbt"].perturb, list | tuple):
            kwargs["pbt"] = dataclasses.replace(kwargs["pbt"], perturb=tuple(kwargs["pbt"].perturb))
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
        for name in ("oracle", "pretrain", "population", "grapher", "fcp", "pbt", "validation"):
            out[name] = dataclasses.asdict(getattr(self, name))
        out["oracle"]["hidden"] = list(self.oracle.hidden)
        out["pbt"]["perturb"] = list(self.pbt.perturb)
        return out

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


def _fields(cls: type, data: Any, prefix: str) -> dict[str, Any]:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{prefix.rstrip('.') or 'config'} must be a mapping, got {data!r}")
    return consume_fields(cls, data, prefix)
