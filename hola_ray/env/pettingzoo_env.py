"""`PursuitEnv`: the pursuit arena as a PettingZoo `ParallelEnv` over the batched core."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import INITIAL_STATE_KEYS, BatchedPursuit


class PursuitEnv(ParallelEnv):
    """n_p pursuers (`pursuer_0`, …) chase n_e scripted evaders (docs/contract.md §1–§2).

    Actions are `Box(0, 1, (1,))`: a turn of (2a − 1)·max_turn. A pursuer that collides
    terminates; the episode ends when every evader is caught or every pursuer is disabled,
    and is truncated at the horizon. With `env.team` (contract §6.3) the agents are the
    pursuers in play: one that leaves terminates, one that joins appears among `agents`
    with its first observation. When it ends, `infos[agent]` holds the episode metrics
    (success, collision, length, captures, team_return).

    `reset(seed=…, options=…)`: options may fix the initial state with any subset of
    `pursuer_pos` [n_p, 2], `pursuer_heading` [n_p], `evader_pos` [n_e, 2],
    `evader_heading` [n_e]; an out-of-arena position is an error, other keys are ignored
    with a warning (PettingZoo requires reset to accept any options).
    """

    metadata = {"name": "hola_pursuit_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}

    def __init__(self, config: PursuitConfig | None = None, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}"
            )
        self.config = config or PursuitConfig()
        self.render_mode = render_mode
        self.core = BatchedPursuit(self.config, 1)
        self.possible_agents = [f"pursuer_{i}" for i in range(self.config.n_pursuers)]
        self.agents: list[str] = []
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        self._actions = np.full((1, self.config.n_pursuers), 0.5)
        self._seeded = False
        self._obs_low, self._obs_high = self.core.layout.bounds()

    # ---- spaces ------------------------------------------------------------------------
    @functools.cache  # noqa: B019 - one space object per agent, as PettingZoo expects
    def observation_space(self, agent: str) -> spaces.Box:
        return spaces.Box(self._obs_low, self._obs_high, dtype=np.float32)

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> spaces.Box:
        return spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float32)

    # ---- episode -----------------------------------------------------------------------
    def reset(
        self, seed: int | None = None, options: Mapping[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
        if seed is None and not self._seeded:
            seed = int(np.random.SeedSequence().generate_state(1, dtype=np.uint64)[0])
        self._seeded = True
        overrides = None
        if options:
            unknown = sorted(set(options) - set(INITIAL_STATE_KEYS))
            if unknown:
                # PettingZoo's contract is that reset accepts any options (its api test
                # passes {"options": 1}), so a stray key is a warning, not an error.
                warnings.warn(
                    f"ignoring unknown reset option(s) {unknown}; "
                    f"known: {list(INITIAL_STATE_KEYS)}",
                    stacklevel=2,
                )
            state = {k: v for k, v in options.items() if k in INITIAL_STATE_KEYS}
            overrides = {0: state} if state else None
        self.core.reset(seeds=None if seed is None else [seed], initial_state=overrides)
        in_play = self.core.pursuer_present[0]
        self.agents = [a for a in self.possible_agents if in_play[self._index[a]]]
        return self._observations(), {agent: {} for agent in self.agents}

    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        unknown = [a for a in actions if a not in self._index]
        if unknown:
            raise ValueError(f"unknown agent(s) {unknown}; agents: {self.possible_agents}")
        finished = [a for a in actions if a not in self.agents]
        if finished:
            raise ValueError(
                f"action for {finished}, no longer in the episode (disabled); live: {self.agents}"
            )
        missing = [agent for agent in self.agents if agent not in actions]
        if missing:
            raise ValueError(f"no action for live agent(s) {missing}")
        for agent in self.agents:
            raw = actions[agent]
            if raw is None:
                raise ValueError(f"action of {agent} is None")
            try:
                value = np.asarray(raw, dtype=np.float64).reshape(-1)
            except (TypeError, ValueError):
                raise ValueError(f"action of {agent} is not a number: {raw!r}") from None
            if value.size != 1:
                raise ValueError(f"action of {agent} must hold one number, got {value}")
            if not np.isfinite(value[0]):
                raise ValueError(f"action of {agent} is {value[0]}: it must be a finite number")
            self._actions[0, self._index[agent]] = value[0]
        result = self.core.step(self._actions)

        live = self.agents
        ended = bool(result.terminated[0])
        truncated = bool(result.truncated[0])
        in_play, active = self.core.pursuer_present[0], self.core.pursuer_active[0]
        # a teammate that left (landed) ends its own episode; one that joined starts its own
        joined = [
            a for a in self.possible_agents
            if active[self._index[a]] and a not in live and not (ended or truncated)
        ]  # fmt: skip
        rewards = {a: float(result.reward[0, self._index[a]]) for a in live}
        terminations = {
            a: ended or bool(result.disabled[0, self._index[a]]) or not in_play[self._index[a]]
            for a in live
        }
        truncations = {a: truncated for a in live}
        if ended or truncated:
            metrics = self.core.episode_metrics(0)
            # `terminated`: whether the agent's own episode ended here (a truncated one
            # did not: `hola_ray.env.horizon`)
            infos = {a: dict(metrics) | {"terminated": terminations[a]} for a in live}
        else:
            infos = {a: {} for a in live}
        self.agents = [a for a in live if not (terminations[a] or truncations[a])] + joined
        obs = {a: self.core.obs[0, self._index[a]].copy() for a in [*live, *joined]}
        for a in joined:  # in play from this step: no reward yet, its episode running
            rewards[a], terminations[a], truncations[a], infos[a] = 0.0, False, False, {}
        return obs, rewards, terminations, truncations, infos

    def _observations(self) -> dict[str, np.ndarray]:
        return {a: self.core.obs[0, self._index[a]].copy() for a in self.agents}

    def state(self) -> np.ndarray:
        """The true state: pursuer (x, y, θ, active) then evader (x, y, θ, alive) rows, flat."""
        core = self.core
        pursuers = np.column_stack(
            [core.pursuer_pos[0], core.pursuer_heading[0], core.pursuer_active[0]]
        )
        evaders = np.column_stack(
            [core.evader_pos[0], core.evader_heading[0], core.evader_alive[0]]
        )
        return np.concatenate([pursuers.ravel(), evaders.ravel()]).astype(np.float32)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            return None
        from hola_ray.env.render import render_frame

        return render_frame(self.config, self.core, 0)

    def close(self) -> None:
        pass
