"""Play N episodes of any mix of policies on the batched core; report contract §1.6's metrics."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, fields

import numpy as np
import torch

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.evaluation.metrics import TEAM
from hola_ray.evaluation.stats import episode_seeds as derive_seeds
from hola_ray.evaluation.stats import mean_and_se
from hola_ray.policies.base import Policy, seated
from hola_ray.policies.learned import MLPPolicy, MLPStack

Dynamics = Callable[[BatchedPursuit], Callable[[np.ndarray], np.ndarray]]
"""Outside dynamics: env → (actions [B, n_p] → the pursuers' positions after the step)."""


class PolicyError(ValueError):
    """A policy whose actions are not a finite array with one action per observation row."""

    @classmethod
    def check(cls, name: str, actions: object, rows: int) -> np.ndarray:
        """`actions` as a float array [rows], or this error naming the policy."""
        try:
            out = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise cls(f"{name}: act returned {type(actions).__name__}, not numbers") from err
        if out.shape != (rows,):
            raise cls(f"{name}: act returned shape {out.shape} for {rows} observations")
        if not np.isfinite(out).all():
            raise cls(f"{name}: act returned a non-finite action (NaN or inf)")
        return out


@dataclass(frozen=True)
class RolloutResult:
    """Per-episode outcomes and their means with standard errors."""

    success: np.ndarray  # [N] bool: every evader captured
    collision: np.ndarray  # [N] bool: at least one collision
    length: np.ndarray  # [N] int: steps until termination (horizon if truncated)
    team_return: np.ndarray  # [N] float: summed return of all pursuers
    captures: np.ndarray  # [N] int: evaders captured
    crashed: np.ndarray  # [N, n_p] bool: the pursuer in that seat collided (and dropped out)
    played: np.ndarray  # [N, n_p] bool: the seat was in play at some step (all of a whole team)

    @property
    def episodes(self) -> int:
        return int(self.success.shape[0])

    def part(self, start: int, stop: int) -> RolloutResult:
        """Episodes start … stop − 1 alone (one hyperedge's of a batched rollout)."""
        return RolloutResult(*(getattr(self, f.name)[start:stop] for f in fields(self)))

    def summary(self) -> dict[str, float]:
        """Rates and means with their standard errors, as plain floats."""
        out: dict[str, float] = {"episodes": float(self.episodes)}
        for name in (m.field for m in TEAM):
            mean, se = mean_and_se(getattr(self, name))
            out[name] = mean
            out[f"{name}_se"] = se
        return out


def rollout(
    config: PursuitConfig,
    policies: Sequence[Policy],
    episodes: int,
    assignment: np.ndarray | None = None,
    seed: int = 0,
    batch_size: int = 1024,
    episode_seeds: np.ndarray | None = None,
    dynamics: Dynamics | None = None,
    batched: bool = True,
) -> RolloutResult:
    """Play `episodes` episodes to their end and collect their metrics.

    policies: with no `assignment`, one policy per pursuer slot (len == n_pursuers);
        otherwise the candidates that `assignment` indexes. An object listed more than once
        plays each listing as a separate copy (`seated`): per-row state is never shared.
    assignment: [episodes, n_pursuers] ints, the policy of each slot in each episode.
    seed: the run seed; episode i always gets the same derived seed for a given run seed.
    batch_size: most episodes simulated at once.
    episode_seeds: [episodes] explicit episode seeds instead of those derived from `seed`
        (to replay the same episodes with different teams).
    dynamics: how the pursuers really move (`hola_ray.flight.Crazyflies`): called with each
        batch's env, it gives a function of the step's actions that returns where each
        pursuer is at the end of the step; None is the arena's kinematic move.
    batched: learned policies of one layout in one stacked forward pass (`MLPStack`), and
        stateless policies asked for the rows of running episodes only; False: every policy
        on every row it seats, one forward pass each (the reference the tests hold the
        batched path to: the same episodes, to within the float rounding of the stack).
    """
    n_p = config.n_pursuers
    policies = seated(policies)
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if assignment is None:
        if len(policies) != n_p:
            raise ValueError(
                f"give one policy per pursuer slot ({n_p}) or an assignment; got {len(policies)}"
            )
        assignment = np.broadcast_to(np.arange(n_p), (episodes, n_p))
    assignment = np.asarray(assignment)
    if assignment.shape != (episodes, n_p):
        raise ValueError(f"assignment must have shape {(episodes, n_p)}, got {assignment.shape}")
    if assignment.min() < 0 or assignment.max() >= len(policies):
        raise ValueError(f"assignment indexes policies 0..{len(policies) - 1} only")

    if episode_seeds is None:
        seeds = derive_seeds(seed, episodes)
    else:
        seeds = np.asarray(episode_seeds)
        if seeds.shape != (episodes,):
            raise ValueError(f"episode_seeds must have shape {(episodes,)}, got {seeds.shape}")
    parts = []
    with _one_thread():
        for start in range(0, episodes, batch_size):
            stop = min(start + batch_size, episodes)
            parts.append(
                _play(
                    config, policies, assignment[start:stop], seeds[start:stop], dynamics, batched
                )
            )
    return RolloutResult(*(np.concatenate(column) for column in zip(*parts, strict=True)))


def _play(
    config: PursuitConfig,
    policies: Sequence[Policy],
    assignment: np.ndarray,  # [B, n_p]
    seeds: np.ndarray,  # [B]
    dynamics: Dynamics | None = None,
    batched: bool = True,
) -> tuple[np.ndarray, ...]:
    batch = assignment.shape[0]
    env = BatchedPursuit(config, batch)
    obs = env.reset(seeds=seeds)
    fly = dynamics(env) if dynamics is not None else None
    masks = [assignment == k for k in range(len(policies))]
    for policy, mask in zip(policies, masks, strict=True):
        if mask.any():
            policy.reset(np.ones(int(mask.sum()), dtype=bool))
    stack, stacked = _stack(policies, masks) if batched else (None, [])
    played = env.pursuer_present.copy()
    slot = np.full(assignment.shape, -1)  # [B, n_p] the seat's actor in the stack, or −1
    for k, policy_index in enumerate(stacked):
        slot[masks[policy_index]] = k
    actions = np.full((batch, config.n_pursuers), 0.5)
    while not env.done.all():
        running = ~env.done[:, None]  # [B, 1] a finished episode's actions are not read
        for k, (policy, mask) in enumerate(zip(policies, masks, strict=True)):
            if k in stacked:
                continue
            if batched and _keeps_no_state(policy):
                mask = mask & running
            if mask.any():
                rows = obs[mask]
                name = getattr(policy, "name", type(policy).__name__)
                actions[mask] = PolicyError.check(name, policy.act(rows), len(rows))
        if stack is not None:
            seats = (slot >= 0) & running
            actions[seats] = stack.act(obs[seats], slot[seats])
        waiting = env.pursuer_waiting & running
        obs = env.step(actions, fly(actions) if fly is not None else None).obs
        joined = waiting & env.pursuer_present  # a teammate that came into play: its
        if joined.any():  # policy starts its episode there (a D3QN-G's pair drawn afresh)
            for policy, mask in zip(policies, masks, strict=True):
                if (joined & mask).any():
                    policy.reset(joined[mask])
        played |= env.pursuer_present
    return (
        env.success.copy(),
        env.collided.copy(),
        env.t.copy(),
        env.episode_return.sum(axis=1),
        env.captures.copy(),
        env.pursuer_present & ~env.pursuer_active,  # crashed in play (not landed or waiting)
        played,
    )


@contextmanager
def _one_thread() -> Iterator[None]:
    """torch on one thread for the rollout: a stacked forward pass rounds its last bit by the
    thread count, and a run's episodes must play alike in a driver on two threads and in an
    actor or a Ray task on one (the smoke run and its experiment trial agree to the bit)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def _keeps_no_state(policy: object) -> bool:
    """A policy that keeps no per-row state (its `reset` is `Policy`'s): it may be asked for
    the rows of running episodes alone. One that keeps state is bound to its rows, finished
    episodes' too."""
    return isinstance(policy, Policy) and type(policy).reset is Policy.reset


def _stack(
    policies: Sequence[Policy], masks: Sequence[np.ndarray]
) -> tuple[MLPStack | None, list[int]]:
    """The learned policies that seat anyone, as one `MLPStack` when two or more of them
    share a layout (the largest such group), and their indices in `policies`."""
    learned = [k for k, p in enumerate(policies) if type(p) is MLPPolicy and masks[k].any()]
    groups: list[list[int]] = []
    for k in learned:
        group = next(
            (g for g in groups if MLPStack.compatible([policies[g[0]], policies[k]])), None
        )
        if group is None:
            groups.append([k])
        else:
            group.append(k)
    best = max(groups, key=len, default=[])
    if len(best) < 2:
        return None, []
    return MLPStack([policies[k] for k in best]), best
