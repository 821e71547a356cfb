"""Record one episode's true state step by step, for replays and plots."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.env.trajectory import Trajectory
from hola_ray.evaluation.rollout import Dynamics
from hola_ray.policies.base import Policy, seated


def record(
    config: PursuitConfig,
    team: Sequence[Policy],
    seed: int = 0,
    initial_state: Mapping[str, np.ndarray] | None = None,
    dynamics: Dynamics | None = None,
) -> Trajectory:
    """Play one episode with `team[i]` in pursuer slot i and record every state;
    `dynamics` as in `rollout` (None: the arena's kinematic move)."""
    if len(team) != config.n_pursuers:
        raise ValueError(f"team must hold {config.n_pursuers} policies, got {len(team)}")
    env = BatchedPursuit(config, 1)
    obs = env.reset(seeds=[seed], initial_state={0: initial_state} if initial_state else None)
    # one player per seat, as in `rollout`: an object in several seats plays as copies
    players = seated(team)
    fly = dynamics(env) if dynamics is not None else None
    for policy in players:
        policy.reset(np.ones(1, dtype=bool))
    frames: dict[str, list[np.ndarray]] = {
        key: []
        for key in (
            "pursuer_pos",
            "pursuer_heading",
            "pursuer_active",
            "pursuer_present",
            "evader_pos",
            "evader_heading",
            "evader_alive",
        )
    }
    captures: list[tuple[int, int, tuple[float, float]]] = []
    collisions: list[tuple[int, int, tuple[float, float]]] = []

    def snapshot() -> None:
        for key, store in frames.items():
            store.append(getattr(env, key)[0].copy())

    snapshot()
    actions = np.empty((1, config.n_pursuers))
    while not env.done[0]:
        for seat, policy in enumerate(players):
            actions[0, seat] = policy.act(obs[0, seat : seat + 1])[0]
        alive_before = env.evader_alive[0].copy()
        result = env.step(actions, fly(actions) if fly is not None else None)
        obs = result.obs
        for e in np.flatnonzero(alive_before & ~env.evader_alive[0]):
            captures.append((int(env.t[0]), int(e), tuple(env.evader_pos[0, e].tolist())))
        for i in np.flatnonzero(result.disabled[0]):
            collisions.append((int(env.t[0]), int(i), tuple(env.pursuer_pos[0, i].tolist())))
        snapshot()
    return Trajectory(
        **{key: np.stack(store) for key, store in frames.items()},
        captures=captures,
        collisions=collisions,
        metrics=env.episode_metrics(0),
        policy_names=[p.name for p in team],
        arena=env.arena_of(0),
    )
