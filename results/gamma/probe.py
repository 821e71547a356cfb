"""The probe behind configs/experiments/gamma.yaml: how much a crash costs a learner in
discounted return. The learner sits in seat 0 beside the first n_p − 1 validation
teammates (what training may see); for each discount it prints the mean return-to-go
of the learner's live steps in the episodes it survives and in those where it crashes.

    python results/gamma/probe.py runs/acceptance/trials/hola_m3-s0/best.pt [...] [--episodes 200]

It measures; it chooses nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from hola_ray.env.config import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.evaluation.pools import validation_mates
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.policies.base import seated
from hola_ray.policies.registry import load_policy, trained_scenario

DISCOUNTS = (0.99, 0.997, 1.0)


def play(path: Path, episodes: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The learner's reward per step [T, E], whether it flew [T, E], whether it crashed [E]."""
    config = PursuitConfig.from_dict(trained_scenario(path))
    mates = validation_mates(config, config.n_pursuers - 1)
    team = seated([load_policy(path, config), *mates])
    env = BatchedPursuit(config, episodes)
    obs = env.reset(seeds=episode_seeds(seed, episodes))
    for policy in team:
        policy.reset(np.ones(episodes, dtype=bool))
    rewards, flying, crashed = [], [], np.zeros(episodes, dtype=bool)
    while not env.done.all():
        live = env.pursuer_active[:, 0] & ~env.done
        actions = np.stack([team[i].act(obs[:, i]) for i in range(config.n_pursuers)], axis=1)
        step = env.step(actions)
        obs = step.obs
        rewards.append(np.where(live, step.reward[:, 0], 0.0))
        flying.append(live)
        crashed |= step.disabled[:, 0]
    return np.array(rewards), np.array(flying), crashed


def main() -> None:
    parser = argparse.ArgumentParser(prog="python results/gamma/probe.py", description=__doc__)
    parser.add_argument("policies", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args()
    for path in args.policies:
        rewards, flying, crashed = play(path, args.episodes, args.seed)
        print(f"{path}: the learner crashes in {crashed.mean():.0%} of {args.episodes} episodes")
        for gamma in DISCOUNTS:
            to_go, acc = np.zeros_like(rewards), np.zeros(rewards.shape[1])
            for t in range(len(rewards) - 1, -1, -1):
                acc = rewards[t] + gamma * acc
                to_go[t] = acc
            survived = to_go[flying & ~crashed[None, :]].mean()
            crashing = to_go[flying & crashed[None, :]].mean()
            print(
                f"  γ = {gamma}: return-to-go when it survives {survived:.2f}, when it crashes "
                f"{crashing:.2f}, difference {survived - crashing:.2f}"
            )


if __name__ == "__main__":
    main()
