"""The batched pursuit core: B independent episodes stepped at once (docs/contract.md §1–§2).

Each episode owns its random stream, so episode b of a batch replays exactly as a single
environment given the same seed, whatever else the batch holds. A finished episode stays
frozen (zero reward, no movement) until it is reset.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env import _kernels, _rng

INITIAL_STATE_KEYS = ("pursuer_pos", "pursuer_heading", "evader_pos", "evader_heading")
"""The keys an initial-state override may hold (any subset)."""


@dataclass(frozen=True)
class StepResult:
    """What one batched step returns; arrays are views the next step overwrites."""

    obs: np.ndarray  # [B, n_p, obs_dim] float32
    reward: np.ndarray  # [B, n_p] float64
    terminated: np.ndarray  # [B] bool: the episode ended this step (success or all disabled)
    truncated: np.ndarray  # [B] bool: the episode hit the horizon this step
    disabled: np.ndarray  # [B, n_p] bool: the pursuer collided this step


class BatchedPursuit:
    """B pursuit episodes in numpy arrays, stepped by one compiled kernel."""

    def __init__(self, config: PursuitConfig, batch_size: int) -> None:
        if not isinstance(batch_size, int | np.integer) or batch_size < 1:
            raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
        self.config = config
        self.layout = config.layout
        self.batch_size = B = int(batch_size)
        n_p, n_e = config.n_pursuers, config.n_evaders
        self._params = _kernels.pack_params(config)
        self._arena = _kernels.Arena(
            ppos=np.zeros((B, n_p, 2)),
            phead=np.zeros((B, n_p)),
            pactive=np.zeros((B, n_p), dtype=bool),
            epos=np.zeros((B, n_e, 2)),
            ehead=np.zeros((B, n_e)),
            ealive=np.zeros((B, n_e), dtype=bool),
            wander_left=np.zeros((B, n_e), dtype=np.int64),
            wander_dir=np.zeros((B, n_e)),
            slip=np.zeros((B, n_e), dtype=bool),
            slip_dir=np.zeros((B, n_e, 2)),
            t=np.zeros(B, dtype=np.int64),
            done=np.ones(B, dtype=bool),  # nothing runs before the first reset
            collided=np.zeros(B, dtype=bool),
            captures=np.zeros(B, dtype=np.int64),
            ep_return=np.zeros((B, n_p)),
            rng=_rng.seed_state(np.arange(B)),
            pvel=np.zeros((B, n_p, 2)),
            pcmd=np.zeros((B, n_p, 2)),
            ppresent=np.zeros((B, n_p), dtype=bool),
            pwaiting=np.zeros((B, n_p), dtype=bool),
            change_t=np.zeros((B, max(config.team.changes, 1)), dtype=np.int64),
            team_rng=np.zeros((B, max(config.team.changes, 1) + 1), dtype=np.uint64),
            layout=np.zeros(B, dtype=np.int64),
        )
        self._out = _kernels.StepOut(
            obs=np.zeros((B, n_p, self.layout.dim), dtype=np.float32),
            reward=np.zeros((B, n_p)),
            terminated=np.zeros(B, dtype=bool),
            truncated=np.zeros(B, dtype=bool),
            disabled=np.zeros((B, n_p), dtype=bool),
            new_heading=np.zeros((B, n_e)),
            dist_prev=np.zeros((B, n_p, n_e)),
        )
        self._kinematic = np.zeros((0, n_p, 2))  # `step`'s placed: none, move kinematically
        # Public views of the kernel arrays (the same objects, updated in place).
        arena = self._arena
        self.pursuer_pos = arena.ppos  # [B, n_p, 2] metres
        self.pursuer_heading = arena.phead  # [B, n_p] radians
        self.pursuer_active = arena.pactive  # [B, n_p] bool: in play and not crashed
        self.pursuer_present = arena.ppresent  # [B, n_p] bool: in play (crashed or not)
        self.pursuer_waiting = arena.pwaiting  # [B, n_p] bool: not yet in play, may join
        self.evader_pos = arena.epos  # [B, n_e, 2]
        self.evader_heading = arena.ehead  # [B, n_e]
        self.evader_alive = arena.ealive  # [B, n_e] bool
        self.t = arena.t  # [B] steps taken in the episode
        self.done = arena.done  # [B] episodes that have ended (or never started)
        self.collided = arena.collided  # [B] a collision happened in the episode
        self.captures = arena.captures  # [B] evaders captured in the episode
        self.episode_return = arena.ep_return  # [B, n_p] each pursuer's summed reward
        self.obs = self._out.obs  # [B, n_p, obs_dim] float32
        self.layout_index = arena.layout  # [B] the episode's arena: an index of `arenas`

    def arena_of(self, b: int) -> str:
        """The arena episode b is played in (drawn at its reset where `env.arenas` is set)."""
        mix = self.config.arenas
        return mix[int(self.layout_index[b])] if mix else self.config.arena

    def config_of(self, b: int) -> PursuitConfig:
        """The scenario as episode b plays it: in its own arena, drawing no other."""
        return self.config.in_arena(self.arena_of(b)) if self.config.arenas else self.config

    # ---- reset -----------------------------------------------------------------------
    def reset(
        self,
        seeds: Sequence[int] | np.ndarray | None = None,
        mask: np.ndarray | None = None,
        initial_state: Mapping[int, Mapping[str, np.ndarray]] | None = None,
    ) -> np.ndarray:
        """Reset the episodes in `mask` (all by default) and return the whole batch's obs.

        seeds: one integer per reset episode (in batch order), reseeding its stream; without
            it each stream continues, so successive resets give fresh episodes.
        initial_state: episode index → overrides (keys of `INITIAL_STATE_KEYS`) applied after
            the random draw.
        """
        mask = self._mask(mask)
        if seeds is not None:
            seeds = np.asarray(seeds).reshape(-1)
            if seeds.shape[0] != int(mask.sum()):
                raise ValueError(
                    f"seeds must hold one seed per reset episode ({int(mask.sum())}), "
                    f"got {seeds.shape[0]}"
                )
            self._arena.rng[mask] = _rng.seed_state(seeds)
        _kernels.reset_masked(mask, self._params, self._arena, self.obs)
        if initial_state:
            fixed = np.zeros(self.batch_size, dtype=bool)
            for b, overrides in initial_state.items():
                if not mask[b]:
                    raise ValueError(f"initial_state given for episode {b}, which is not reset")
                self._apply_initial_state(int(b), overrides)
                fixed[b] = True
            self._observe(fixed)
        return self.obs

    def _apply_initial_state(self, b: int, overrides: Mapping[str, np.ndarray]) -> None:
        unknown = sorted(set(overrides) - set(INITIAL_STATE_KEYS))
        if unknown:
            raise ValueError(
                f"unknown initial-state key(s) {unknown}; allowed: {list(INITIAL_STATE_KEYS)}"
            )
        cfg = self.config
        shapes = {
            "pursuer_pos": (cfg.n_pursuers, 2),
            "pursuer_heading": (cfg.n_pursuers,),
            "evader_pos": (cfg.n_evaders, 2),
            "evader_heading": (cfg.n_evaders,),
        }
        for key, value in overrides.items():
            value = np.asarray(value, dtype=np.float64)
            if value.shape != shapes[key]:
                raise ValueError(f"{key} must have shape {shapes[key]}, got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{key} must be finite, got {value}")
            if key.endswith("_pos"):
                inside = (
                    (value[:, 0] >= 0)
                    & (value[:, 0] <= cfg.arena_width)
                    & (value[:, 1] >= 0)
                    & (value[:, 1] <= cfg.arena_height)
                )
                if not inside.all():
                    raise ValueError(
                        f"{key} must lie inside the arena [0, {cfg.arena_width}] × "
                        f"[0, {cfg.arena_height}], got {value[~inside].tolist()}"
                    )
            getattr(self, key)[b] = value

    def _observe(self, mask: np.ndarray) -> None:
        _kernels.observe_all(mask, self._params, self._arena, self.obs)

    def _mask(self, mask: np.ndarray | None) -> np.ndarray:
        if mask is None:
            return np.ones(self.batch_size, dtype=bool)
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.batch_size,):
            raise ValueError(f"mask must have shape ({self.batch_size},), got {mask.shape}")
        return mask

    # ---- step ------------------------------------------------------------------------
    def step(self, actions: np.ndarray, placed: np.ndarray | None = None) -> StepResult:
        """Advance every running episode; actions [B, n_p] in [0, 1] (clipped; NaN is an error).

        placed: [B, n_p, 2] where each pursuer is at the end of the step, flown there by
            outside dynamics (`hola_ray.flight`) that tracked the heading its action
            commands: an active pursuer takes that heading and this position instead of
            the kinematic move. The evaders still decide on the positions before the step,
            and captures and collisions are judged where the pursuers are after it.
        """
        actions = np.asarray(actions, dtype=np.float64)
        expected = (self.batch_size, self.config.n_pursuers)
        if actions.shape != expected:
            raise ValueError(f"actions must have shape {expected}, got {actions.shape}")
        if np.isnan(actions).any():
            where = np.argwhere(np.isnan(actions))[:3].tolist()
            raise ValueError(f"NaN action(s) at [episode, pursuer] {where}")
        actions = np.clip(actions, 0.0, 1.0)
        if placed is None:
            placed = self._kinematic
        else:
            placed = np.ascontiguousarray(placed, dtype=np.float64)
            if placed.shape != (*expected, 2) or not np.isfinite(placed).all():
                raise ValueError(f"placed must be finite positions {(*expected, 2)}")
        _kernels.step_all(actions, placed, self._params, self._arena, self._out)
        out = self._out
        return StepResult(out.obs, out.reward, out.terminated, out.truncated, out.disabled)

    # ---- metrics ---------------------------------------------------------------------
    @property
    def success(self) -> np.ndarray:
        """[B] bool: every evader has been captured."""
        return self.captures >= self.config.n_evaders

    def episode_metrics(self, b: int) -> dict[str, float | int | bool]:
        """the metrics of contract §1.6 of episode b as it stands (final once it is done)."""
        return {
            "success": bool(self.success[b]),
            "collision": bool(self.collided[b]),
            "length": int(self.t[b]),
            "captures": int(self.captures[b]),
            "team_return": float(self.episode_return[b].sum()),
        }
