"""The probe behind configs/experiments/approach.yaml: what the approach term pays a learner
in the steps before it crashes. The learner sits in seat 0 beside the first n_p − 1
validation teammates (what training may see); for each of its live steps the probe
computes the approach term both ways from the positions, the contract's (`distance`: d_now after
both moves) and `own_move` (d_now to where the evader was), and prints their means over
all live steps and over the last `--window` steps before each of its crashes.

    python results/approach/probe.py runs/gamma/trials/hola-s0/best.pt [...] [--episodes 200]

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


def play(path: Path, episodes: int, seed: int) -> dict[str, np.ndarray]:
    """Per step [T, E]: the learner's approach term both ways and whether it flew; and
    per episode [E] the step of its crash (−1: none)."""
    config = PursuitConfig.from_dict(trained_scenario(path))
    mates = validation_mates(config, config.n_pursuers - 1)
    team = seated([load_policy(path, config), *mates])
    env = BatchedPursuit(config, episodes)
    obs = env.reset(seeds=episode_seeds(seed, episodes))
    for policy in team:
        policy.reset(np.ones(episodes, dtype=bool))
    scale = config.reward.approach_scale
    both, own, flying = [], [], []
    crash_step = np.full(episodes, -1)
    while not env.done.all():
        live = env.pursuer_active[:, 0] & ~env.done
        alive = env.evader_alive.copy()
        p0, e0 = env.pursuer_pos[:, 0].copy(), env.evader_pos.copy()
        actions = np.stack([team[i].act(obs[:, i]) for i in range(config.n_pursuers)], axis=1)
        step = env.step(actions)
        obs = step.obs
        p1, e1 = env.pursuer_pos[:, 0], env.evader_pos
        d0 = np.linalg.norm(e0 - p0[:, None], axis=-1)
        gain_both = ((d0 - np.linalg.norm(e1 - p1[:, None], axis=-1)) * alive).sum(-1) / scale
        gain_own = ((d0 - np.linalg.norm(e0 - p1[:, None], axis=-1)) * alive).sum(-1) / scale
        both.append(np.where(live, gain_both, 0.0))
        own.append(np.where(live, gain_own, 0.0))
        flying.append(live)
        crash_step[(crash_step < 0) & step.disabled[:, 0]] = len(flying) - 1
    return {
        "distance": np.array(both),
        "own_move": np.array(own),
        "flying": np.array(flying),
        "crash_step": crash_step,
    }


def main() -> None:
    parser = argparse.ArgumentParser(prog="python results/approach/probe.py", description=__doc__)
    parser.add_argument("policies", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--window", type=int, default=100)
    args = parser.parse_args()
    for path in args.policies:
        run = play(path, args.episodes, args.seed)
        crashed = run["crash_step"] >= 0
        before = np.zeros_like(run["flying"])
        for e in np.flatnonzero(crashed):
            k = run["crash_step"][e]
            before[max(0, k - args.window) : k + 1, e] = True
        print(f"{path}: the learner crashes in {crashed.mean():.0%} of {args.episodes} episodes")
        for mode in ("distance", "own_move"):
            term = run[mode]
            print(
                f"  {mode:9s}: per live step {term[run['flying']].mean():+.3f}; "
                f"over the {args.window} steps before a crash {term[before].mean():+.3f} a step, "
                f"{term[before].sum() / max(crashed.sum(), 1):+.1f} in all"
            )


if __name__ == "__main__":
    main()
