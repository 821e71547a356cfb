"""Training D3QN-G with RLlib's DQN (new API stack): see `hola_ray.policies.d3qn`.

    python -m hola_ray.oracle.d3qn_train configs/pools/d3qn-g-1.yaml runs/pools/d3qn-g-1

`python -m hola_ray pools build --pool het` calls `train_d3qn` for each D3QN-G member; a
finished run directory (its `export.pt`) is reused, never retrained.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
import yaml
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.env.multi_agent_env import MultiAgentEnv
from ray.tune.registry import register_env

from hola_ray.config.reader import (
    ConfigError,
    checked,
    consume_fields,
    finite_in,
    load_yaml,
    located,
    positive_int,
    require,
    widths,
)
from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.horizon import horizon_is_truncation
from hola_ray.env.pettingzoo_env import PursuitEnv
from hola_ray.policies.d3qn import D3QNG, FORMAT, PairActor, dacoop_state, state_dim

ENV_NAME = "hola_ray_d3qn"
MODULE = "d3qn"


@dataclass(frozen=True)
class D3QNSettings:
    """The DQN's settings (DACOOP-A's values where two CPUs allow; see the config files)."""

    env_steps: int = 60_000
    hidden: tuple[int, ...] = (128, 64)
    head_hidden: tuple[int, ...] = (64,)
    lr: float = 3e-4
    gamma: float = 0.99
    batch: int = 128
    buffer: int = 100_000
    alpha: float = 0.6
    beta: float = 0.4
    epsilon_start: float = 1.0
    epsilon_end: float = 0.02
    epsilon_steps: int = 30_000
    target_update: int = 2_000
    learning_starts: int = 2_000
    training_intensity: float = 8.0
    envs: int = 8
    fragment: int = 8
    n_step: int = 1
    decision_interval: int = 1
    """env steps a chosen pair is held (DQN's action repeat); DACOOP-A picks every step"""
    validate_every: int = 0
    """every so many env steps (decisions) the greedy network is validated; 0: never, the
    last network is exported"""
    validate_episodes: int = 60
    """episodes of a validation: three copies vs the run's evaders, the training scenario"""
    select: str = "best"
    """which validated network is exported: `best` (highest validation success, then
    lowest collision) or `nearest` (validation success nearest `target_success`, then
    lowest collision, then the earlier one)"""
    env_runners: int = 1
    """RLlib env runner actors; 0 samples in the training process (the tests' tiny runs:
    no actor to start)"""
    target_success: float | None = None
    """the validation success `select: nearest` aims at (a pool member's paper Table II
    figure: the pool should be as strong as the paper's, not stronger)"""

    def __post_init__(self) -> None:
        s = "d3qn"
        big = 10**11
        positive_int(s, self, "env_steps", "target_update", maximum=big)
        positive_int(s, self, "batch", "fragment", maximum=10**7)
        positive_int(s, self, "buffer", maximum=10**9)
        positive_int(s, self, "envs", maximum=65_536)
        positive_int(s, self, "env_runners", minimum=0, maximum=1024)
        positive_int(s, self, "n_step", "decision_interval", maximum=10_000)
        positive_int(s, self, "validate_episodes", maximum=10**6)
        positive_int(
            s, self, "epsilon_steps", "learning_starts", "validate_every", minimum=0, maximum=big
        )
        widths("d3qn.hidden", self.hidden)
        widths("d3qn.head_hidden", self.head_hidden, allow_empty=True)
        finite_in(s, self, "lr", 1e-8, 1.0, "in [1e-8, 1]")
        for name in ("gamma", "alpha", "beta", "epsilon_start", "epsilon_end"):
            finite_in(s, self, name, 0.0, 1.0, "in [0, 1]")
        finite_in(s, self, "training_intensity", 1e-3, 1e3, "in [0.001, 1000]")
        require(self.select in ("best", "nearest"), "d3qn.select", "best or nearest", self.select)
        if self.select == "nearest" and not (
            isinstance(self.target_success, int | float) and 0 <= self.target_success <= 1
        ):
            raise ConfigError(
                "d3qn.select: nearest needs d3qn.target_success in [0, 1]", "d3qn.target_success"
            )


@dataclass(frozen=True)
class D3QNRun:
    """A D3QN-G config file: the scenario, the seed and the DQN's settings."""

    seed: int
    env: PursuitConfig
    d3qn: D3QNSettings

    @classmethod
    def from_dict(cls, raw: Any) -> D3QNRun:
        """Read with the run config's checks: every malformed value is one `ConfigError`
        naming its field."""
        if not isinstance(raw, Mapping):
            raise ConfigError(f"a D3QN-G config must be a mapping, got {type(raw).__name__}")
        unknown = sorted(set(raw) - {"kind", "seed", "env", "d3qn"})
        if unknown:
            raise ConfigError(
                f"unknown key(s) {', '.join(unknown)}; allowed: d3qn, env, kind, seed", unknown[0]
            )
        require(raw.get("kind") == "d3qn", "kind", "d3qn", raw.get("kind"))
        seed = checked(int, raw.get("seed", 0), "seed")
        require(seed >= 0, "seed", "an integer >= 0", seed)
        settings = raw.get("d3qn", {})
        if not isinstance(settings, Mapping):
            raise ConfigError(f"d3qn must be a mapping, got {settings!r}", "d3qn")
        kwargs = consume_fields(D3QNSettings, settings, "d3qn.")
        try:
            env = PursuitConfig.from_dict(raw.get("env", {}))
        except ConfigError as err:
            raise err.within("env") from None
        return cls(seed=seed, env=env, d3qn=D3QNSettings(**kwargs))

    @classmethod
    def from_yaml(cls, path: str | Path) -> D3QNRun:
        """A D3QN-G config file; errors are one line naming the file, line and field."""
        try:
            return cls.from_dict(load_yaml(path))
        except ConfigError as err:
            raise located(err, path) from None

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "d3qn",
            "seed": self.seed,
            "env": self.env.to_dict(),
            "d3qn": {
                k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self.d3qn).items()
            },
        }


class D3QNEnv(MultiAgentEnv):
    """The arena for the DQN: each pursuer reads its DACOOP-A state and picks an APF-A pair."""

    def __init__(self, env_config: dict[str, Any] | None = None) -> None:
        super().__init__()
        env_config = dict(env_config or {})
        self.interval = int(env_config.get("decision_interval", 1))
        self.config = env_config.get("scenario") or PursuitConfig()
        self.env = PursuitEnv(self.config)
        self.layout = self.config.layout
        self.actor = PairActor(self.config)
        self.agents = self.possible_agents = list(self.env.possible_agents)
        far = self.config.unobserved_distance
        state = gym.spaces.Box(-1.0, far, (state_dim(self.config),), np.float32)
        pairs = gym.spaces.Discrete(len(self.actor.lam))
        self.observation_spaces = {a: state for a in self.agents}
        self.action_spaces = {a: pairs for a in self.agents}
        self._obs: dict[str, np.ndarray] = {}

    def _states(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if not obs:
            return {}
        keys = list(obs)
        rows = dacoop_state(
            np.stack([obs[a] for a in keys]), self.layout, self.config.unobserved_distance
        )
        return {a: rows[i] for i, a in enumerate(keys)}

    def reset(self, *, seed=None, options=None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self._obs = obs
        return self._states(obs), infos

    def step(self, action_dict):
        """Play the chosen pairs for `interval` env steps (fewer if a pursuer's episode
        ends first); each pursuer's reward is its sum over those steps."""
        pairs = {a: int(p) for a, p in action_dict.items()}
        total = dict.fromkeys(pairs, 0.0)
        for _ in range(self.interval):
            keys = [a for a in pairs if a in self._obs]
            full = np.stack([self._obs[a] for a in keys])
            turn = self.actor.act(full, np.array([pairs[a] for a in keys]))
            obs, rewards, terms, truncs, infos = self.env.step(
                {a: np.array([turn[i]], np.float32) for i, a in enumerate(keys)}
            )
            for a, r in rewards.items():
                total[a] += float(r)
            self._obs = obs
            if any(terms.values()) or any(truncs.values()):
                break
        rewards = {a: total[a] for a in rewards}
        terms["__all__"] = not self.env.agents and not any(truncs.values())
        truncs["__all__"] = any(truncs.values())
        return self._states(obs), rewards, terms, truncs, infos


def _make_env(cfg):
    return D3QNEnv(cfg)


class HorizonTruncates(RLlibCallback):
    """An episode cut at the horizon is truncated, not terminated, so the DQN's n-step
    targets bootstrap Q(s_T, ·) there (`hola_ray.env.horizon`)."""

    def on_episode_end(self, *, episode, **kwargs) -> None:
        horizon_is_truncation(episode)


def algorithm_config(run: D3QNRun):
    from ray.rllib.algorithms.dqn import DQNConfig

    s = run.d3qn
    register_env(ENV_NAME, _make_env)  # in this Ray session (Tune's registry lives there)
    return (
        DQNConfig()
        .environment(
            ENV_NAME, env_config={"scenario": run.env, "decision_interval": s.decision_interval}
        )
        .env_runners(
            num_env_runners=s.env_runners,
            num_envs_per_env_runner=s.envs,
            rollout_fragment_length=s.fragment,
        )
        .multi_agent(policies={MODULE}, policy_mapping_fn=lambda aid, ep, **kw: MODULE)
        .rl_module(
            model_config={
                "fcnet_hiddens": list(s.hidden),
                "fcnet_activation": "relu",
                "head_fcnet_hiddens": list(s.head_hidden),
                "head_fcnet_activation": "relu",
                "epsilon": [(0, s.epsilon_start), (s.epsilon_steps, s.epsilon_end)],
            }
        )
        .training(
            double_q=True,
            dueling=True,
            n_step=s.n_step,
            lr=s.lr,
            gamma=s.gamma,
            train_batch_size_per_learner=s.batch,
            target_network_update_freq=s.target_update,
            num_steps_sampled_before_learning_starts=s.learning_starts,
            training_intensity=s.training_intensity,
            replay_buffer_config={
                "type": "MultiAgentPrioritizedEpisodeReplayBuffer",
                "capacity": s.buffer,
                "alpha": s.alpha,
                "beta": s.beta,
            },
        )
        .callbacks(HorizonTruncates)
        # as the Oracle's: no system-usage thread polling psutil, which nothing reads
        .debugging(seed=run.seed, log_level="ERROR", log_sys_usage=False)
    )


def build(run: D3QNRun):
    """RLlib's DQN for `run`, every random draw seeded from the run's seed: RLlib seeds its
    env runners and learner, but its replay buffer draws from an unseeded generator."""
    from hola_ray import third_party

    third_party.apply_rllib()
    algo = algorithm_config(run).build_algo()
    algo.local_replay_buffer.rng = np.random.default_rng(run.seed)
    return algo


def export_from_rllib(state: dict[str, Any], run: D3QNRun) -> dict[str, Any]:
    """The plain-torch export (`D3QNG`) of the DQN module's state."""

    def layers(prefix: str) -> list[tuple[torch.Tensor, torch.Tensor]]:
        idx = sorted(
            int(k[len(prefix) :].split(".")[0])
            for k in state
            if k.startswith(prefix) and k.endswith(".weight")
        )
        return [
            (
                torch.as_tensor(np.asarray(state[f"{prefix}{i}.weight"], np.float32)),
                torch.as_tensor(np.asarray(state[f"{prefix}{i}.bias"], np.float32)),
            )
            for i in idx
        ]

    return {
        "format": FORMAT,
        "state_dim": state_dim(run.env),
        "decision_interval": run.d3qn.decision_interval,
        "activation": "relu",
        "trunk": layers("encoder.net.mlp."),
        "advantage": layers("af.net.mlp."),
        "value": layers("vf.net.mlp."),
    }


VALIDATION_SEED = 7_919
"""Validation episodes' seeds derive from VALIDATION_SEED + the run's seed: apart from
Table II's (seeds 0, 1, 2), and validation plays only the member itself, never a pool."""


def validate(export: dict[str, Any], run: D3QNRun) -> tuple[float, float]:
    """The greedy network's success and collision rates, three copies in the training
    scenario. DACOOP-A saves its network every 500 episodes and validates the last in
    `validation.py`; here the greedy network of a short run swings between validations
    (70 % and 97 % Table II success for two runs of one config), so the exported network
    is chosen among the validated ones (`choose`). Each seat plays its own pair state."""
    from hola_ray.evaluation.rollout import rollout

    policy = D3QNG(run.env, export)
    result = rollout(
        run.env,
        [policy] * run.env.n_pursuers,
        run.d3qn.validate_episodes,
        seed=VALIDATION_SEED + run.seed,
    )
    return round(float(result.success.mean()), 4), round(float(result.collision.mean()), 4)


@dataclass(frozen=True)
class Validated:
    """One validation of the greedy network during training."""

    env_steps: int
    success: float
    collision: float


def choose(validated: list[Validated], settings: D3QNSettings) -> int:
    """The index of the validated network to export, by `settings.select` (see there)."""
    if not validated:
        raise ValueError("no validated network to choose from")
    if settings.select == "best":
        keys = [(-v.success, v.collision, k) for k, v in enumerate(validated)]
    else:
        target = float(settings.target_success)
        keys = [
            (round(abs(v.success - target), 6), v.collision, k) for k, v in enumerate(validated)
        ]
    return min(keys)[-1]


def train_d3qn(
    config_path: str | Path, out: str | Path, progress: bool = True
) -> tuple[Path, dict[str, Any]]:
    """Train (or reuse a finished) D3QN-G run; its export file and what the training did."""
    import ray

    from hola_ray.process import init_local_ray

    out = Path(out)
    done = out / "done.json"
    if done.is_file() and (out / "export.pt").is_file():
        return out / "export.pt", json.loads(done.read_text())
    run = D3QNRun.from_yaml(config_path)
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.yaml").write_text(yaml.safe_dump(run.to_dict(), sort_keys=False))
    if not ray.is_initialized():
        init_local_ray()
    algo = build(run)
    start = time.perf_counter()
    try:
        steps, rows, validated, exports = _train(algo, run, start, out.name, progress)
        if not validated:
            export = _export(algo, run)
            chosen: Validated | None = None
        else:
            k = choose(validated, run.d3qn)
            export, chosen = exports[k], validated[k]
    finally:
        algo.stop()
    with open(out / "progress.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    torch.save(export, out / "export.pt")
    facts = _facts(run, steps, chosen, start)
    done.write_text(json.dumps(facts))
    return out / "export.pt", facts


def _train(
    algo, run: D3QNRun, start: float, name: str, progress: bool
) -> tuple[int, list[dict[str, Any]], list[Validated], list[dict[str, Any]]]:
    """Train to `run.d3qn.env_steps`: the env steps sampled, a progress row per RLlib
    iteration, and the greedy network validated and exported each `validate_every` env
    steps and at the end, for `choose`. With `progress`, the run (`name`) says where it
    is every five iterations and at each validation."""
    steps = 0
    rows = []
    every = run.d3qn.validate_every
    validated: list[Validated] = []
    exports: list[dict[str, Any]] = []
    while steps < run.d3qn.env_steps:
        result = algo.train()
        runners = result.get("env_runners", {})
        before, steps = steps, int(runners.get("num_env_steps_sampled_lifetime", steps))
        row = {
            "env_steps": steps,
            "episode_return": round(float(runners.get("episode_return_mean", np.nan)), 3),
            "episode_length": round(float(runners.get("episode_len_mean", np.nan)), 1),
            "validation_success": "",
            "validation_collision": "",
            "wall_s": round(time.perf_counter() - start, 1),
        }
        if every and (steps // every > before // every or steps >= run.d3qn.env_steps):
            export = _export(algo, run)
            success, collision = validate(export, run)
            row["validation_success"], row["validation_collision"] = success, collision
            validated.append(Validated(steps, success, collision))
            exports.append(export)
            if progress:
                print(
                    f"d3qn {name}: validation at {steps:,} env steps: success "
                    f"{success:.1%}, collision {collision:.1%}",
                    flush=True,
                )
        rows.append(row)
        if progress and len(rows) % 5 == 0:
            print(
                f"d3qn {name}: {steps:,} / {run.d3qn.env_steps:,} env steps, "
                f"return {row['episode_return']}, length {row['episode_length']}, "
                f"{row['wall_s']:.0f} s",
                flush=True,
            )
    return steps, rows, validated, exports


def _export(algo, run: D3QNRun) -> dict[str, Any]:
    """The DQN module's current weights as the plain-torch export."""
    return export_from_rllib(algo.learner_group.get_weights([MODULE])[MODULE], run)


def _facts(run: D3QNRun, steps: int, chosen: Validated | None, start: float) -> dict[str, Any]:
    """done.json: how far the run trained, which network it exported (without validation,
    the last) and, with validation, by which rule and what that network scored."""
    facts = {
        "env_steps": steps,
        "exported_at_env_steps": steps if chosen is None else chosen.env_steps,
        "wall_s": round(time.perf_counter() - start, 1),
    }
    if chosen is not None:
        facts |= {
            "select": run.d3qn.select,
            "target_success": run.d3qn.target_success,
            "validation_success": chosen.success,
            "validation_collision": chosen.collision,
            "validation_episodes": run.d3qn.validate_episodes,
        }
    return facts


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m hola_ray.oracle.d3qn_train")
    parser.add_argument("config", type=Path)
    parser.add_argument("out", type=Path)
    args = parser.parse_args(argv)
    path, facts = train_d3qn(args.config, args.out)
    print(f"D3QN-G export {path}: {facts}")


def script() -> None:
    """`hola-d3qn` (`[project.scripts]`): `main` under the fixed hash seed, as `python -m
    hola_ray.oracle.d3qn_train` runs it (`hola_ray.process.fixed_hash_seed`)."""
    import sys

    from hola_ray.process import fixed_hash_seed, leave, pause_collector

    fixed_hash_seed("hola_ray.oracle.d3qn_train", sys.argv[1:])
    pause_collector()
    main()
    leave(0)


if __name__ == "__main__":
    script()
