"""The Oracle's own configuration (the `oracle` section of a run config) and how it seats
modules: what the Oracle needs and nothing of the method that drives it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hola_ray.config.reader import finite_in, positive_int, require, widths
from hola_ray.config.scenario import PursuitConfig

DISTRIBUTIONS = ("beta", "gaussian")
"""Action distributions an export can hold (oracle.action_dist)."""

SAMPLERS = ("batched", "pettingzoo")
"""oracle.sampler: how the Oracle's env runners sample (OracleConfig.sampler)."""
BUDGETS = ("env_steps", "learner_samples")
"""oracle.budget: what the Oracle's budget counts."""
UPDATES = ("lean", "rllib")
"""oracle.update: how the learner runs a PPO update (OracleConfig.update)."""


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
    """Adam learning rate (at the start, when it decays)"""
    lr_decay_env_steps: int = 0
    """> 0: the learning rate falls linearly from `lr` to `lr_final` over this many env
    steps the Oracle samples (a resumed run, and a build resumed from its last check, go
    on where they stopped), then stays there (RLlib's piecewise-linear lr schedule);
    0 = constant"""
    lr_final: float = 0.0
    """the learning rate the decay ends at (with `lr_decay_env_steps`)"""
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
    update: str = "lean"
    """how the learner runs a PPO update: lean (hola_ray/oracle/learner.py, OracleLearner: the
    frozen partners' rows dropped before GAE, minibatches cut by index, the loss's unused
    terms and per-minibatch logging left out; the same loss and gradients) or rllib (RLlib's
    own pipeline, iterator and loss: the reference the lean path is tested against)"""
    compile: bool = False
    """true: the lean update's loss, forward and backward (hola_ray/oracle/fused.py), is
    compiled by torch.compile at the Oracle's first update (some seconds, cached on disk
    for the next process): about 1.5× the gradient steps per second at the Oracle's sizes,
    the same loss to float rounding. false: the same function run eagerly"""
    overlap: bool = False
    """true: the env runners sample the next train batch while the learner updates on this
    one, one update behind it (hola_ray/oracle/overlap.py); needs remote env runners
    (oracle.env_runners ≥ 1). false: RLlib's PPO, sampling and updating in turn. On in
    configs/default.yaml, configs/sp.yaml and the embedded default (1.25–1.41× the learner
    transitions per second, results/NOTEBOOK.md); off in configs/paper.yaml"""
    sampler: str = "batched"
    """how env runners sample: batched (hola_ray/oracle/batched_runner.py: every vector env
    in one compiled step, one forward pass per module, episodes built in bulk) or
    pettingzoo (RLlib's MultiAgentEnvRunner over the PettingZoo env, step by step)"""

    def validate(self) -> None:
        s = "oracle"
        positive_int(s, self, "env_steps", maximum=10**11)
        positive_int(s, self, "train_batch", "minibatch", maximum=10**8)
        positive_int(s, self, "epochs", maximum=10_000)
        positive_int(s, self, "envs_per_runner", maximum=65_536)
        positive_int(s, self, "env_runners", minimum=0, maximum=10_000)
        require(
            self.minibatch <= self.train_batch,
            "oracle.minibatch",
            f"<= oracle.train_batch ({self.train_batch})",
            self.minibatch,
        )
        finite_in(s, self, "lr", 1e-8, 1.0, "in [1e-8, 1]")
        positive_int(s, self, "lr_decay_env_steps", minimum=0, maximum=10**11)
        finite_in(s, self, "lr_final", 0.0, 1.0, "in [0, 1]")
        finite_in(s, self, "gamma", 0.0, 1.0, "in [0, 1]")
        finite_in(s, self, "gae_lambda", 0.0, 1.0, "in [0, 1]")
        finite_in(s, self, "vf_coef", 0.0, 1e3, "in [0, 1000]")
        finite_in(s, self, "entropy_coef", 0.0, 1.0, "in [0, 1]")
        finite_in(s, self, "clip", 1e-3, 1.0, "in [0.001, 1]")
        finite_in(s, self, "kl_coef", 0.0, 10.0, "in [0, 10]")
        finite_in(s, self, "vf_clip", 1e-3, 1e12, "in [0.001, 1e12]")
        finite_in(s, self, "grad_clip", 0.0, 1e6, "in [0, 1e6] (0 = none)")
        finite_in(s, self, "proximity_length", 0.0, 10.0, "in [0, 10] (0 = off)")
        finite_in(s, self, "gpus_per_learner", 0.0, 64.0, "in [0, 64] (0 = CPU)")
        require(
            self.budget in BUDGETS, "oracle.budget", f"one of {', '.join(BUDGETS)}", self.budget
        )
        require(
            isinstance(self.horizon_terminates, bool),
            "oracle.horizon_terminates",
            "true or false",
            self.horizon_terminates,
        )
        require(isinstance(self.overlap, bool), "oracle.overlap", "true or false", self.overlap)
        require(isinstance(self.compile, bool), "oracle.compile", "true or false", self.compile)
        require(
            self.update in UPDATES, "oracle.update", f"one of {', '.join(UPDATES)}", self.update
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
        widths("oracle.hidden", self.hidden)

    @property
    def lr_schedule(self) -> float | list[list[float]]:
        """RLlib's `lr`: the constant, or [[0, lr], [decay steps, lr_final]]."""
        if not self.lr_decay_env_steps:
            return self.lr
        return [[0, self.lr], [self.lr_decay_env_steps, self.lr_final]]

    def model_features(self, env: PursuitConfig) -> dict[str, Any] | None:
        """The learned policies' proximity features ({"indices", "gain"}), or None."""
        if self.proximity_length == 0:
            return None
        return {
            "indices": env.layout.proximity,
            "gain": env.obs_distance_scale / self.proximity_length,
        }


@dataclass(frozen=True)
class Seating:
    """Who the Oracle's modules are and where they sit: a learner beside `partners` frozen
    partner modules drawn by φ, the learner alone in every seat (self-play, `partners` 0),
    or `mep_members` members trained jointly with the population-entropy bonus `mep_alpha`
    (MEP pre-training; α 0 is plain joint training): each episode one member in every seat
    (`mep_self_play`, as MEP trains its population), or a member drawn per seat."""

    partners: int = 0
    """frozen partner modules `member_0` … (one per population slot); 0 = self-play"""
    mep_members: int = 0
    """> 0: MEP pre-training of that many members, every seat a member"""
    mep_alpha: float = 0.0
    """α of MEP's entropy bonus −log π̄(a|s)"""
    mep_self_play: bool = False
    """MEP pre-training: each episode's seats all one member (drawn uniformly), not a member
    drawn per seat"""

    @property
    def mep(self) -> bool:
        return self.mep_members > 0

    @property
    def self_play(self) -> bool:
        return not self.mep and self.partners == 0
