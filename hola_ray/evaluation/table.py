"""Paper Table II: one evader, three copies of an agent, 50 episodes per seed.

`python -m hola_ray.evaluation.table [--episodes 50] [--seeds 0 1 2]` prints the rows of the
agents that exist so far beside the paper's figures.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence

import numpy as np

from hola_ray.env.config import PursuitConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.stats import mean_and_se
from hola_ray.policies.registry import make_policy

PAPER_TABLE_II = {
    "PPO (1)": (0.90, 321.94),
    "PPO (2)": (0.72, 466.22),
    "Greedy": (0.62, 561.78),
    "VICSEK": (0.98, 295.88),
    "D3QN-G (1)": (0.80, 435.78),
    "D3QN-G (2)": (0.78, 510.34),
}
"""Paper Table II: agent → (success rate, average episode length in steps)."""

AVAILABLE = {"greedy": "Greedy", "vicsek": "VICSEK"}
"""Registry name → Table II row, for the agents implemented so far."""


def table_rows(
    agents: Sequence[str] = tuple(AVAILABLE),
    episodes: int = 50,
    seeds: Sequence[int] = (0, 1, 2),
    config: PursuitConfig | None = None,
) -> list[dict[str, float | str]]:
    """Measure each agent as three copies against one evader; pool episodes over seeds."""
    config = dataclasses.replace(config or PursuitConfig(), n_evaders=1)
    rows = []
    for name in agents:
        policy = make_policy(name, config)
        runs = [rollout(config, [policy] * config.n_pursuers, episodes, seed=s) for s in seeds]
        success = np.concatenate([r.success for r in runs])
        length = np.concatenate([r.length for r in runs])
        collision = np.concatenate([r.collision for r in runs])
        label = AVAILABLE.get(name, policy.name)
        paper_sr, paper_ael = PAPER_TABLE_II.get(label, (float("nan"), float("nan")))
        sr, sr_se = mean_and_se(success)
        ael, ael_se = mean_and_se(length)
        col, col_se = mean_and_se(collision)
        rows.append(
            {
                "agent": label,
                "sr": sr,
                "sr_se": sr_se,
                "ael": ael,
                "ael_se": ael_se,
                "collision": col,
                "collision_se": col_se,
                "paper_sr": paper_sr,
                "paper_ael": paper_ael,
                "episodes": float(success.size),
            }
        )
    return rows


def format_table(rows: list[dict[str, float | str]]) -> str:
    header = (
        f"{'agent':<11} {'SR':>13} {'paper SR':>9} {'ΔSR':>6}   {'AEL (steps)':>15} "
        f"{'paper AEL':>9}   {'collision':>13}  episodes"
    )
    lines = [header, "-" * len(header)]
    for r in rows:
        lines.append(
            f"{r['agent']:<11} {r['sr']:>6.1%} ± {r['sr_se']:>4.1%} {r['paper_sr']:>9.0%} "
            f"{r['sr'] - r['paper_sr']:>+6.0%}   {r['ael']:>7.1f} ± {r['ael_se']:>5.1f} "
            f"{r['paper_ael']:>9.2f}   {r['collision']:>6.1%} ± {r['collision_se']:>4.1%}  "
            f"{int(r['episodes'])}"
        )
    missing = [k for k in PAPER_TABLE_II if k not in {r["agent"] for r in rows}]
    if missing:
        lines.append(f"(not implemented yet: {', '.join(missing)})")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m hola_ray.evaluation.table", description=__doc__
    )
    parser.add_argument("--episodes", type=int, default=50, help="episodes per seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="run seeds")
    parser.add_argument("--agents", nargs="+", default=list(AVAILABLE), help="registry names")
    args = parser.parse_args(argv)
    rows = table_rows(args.agents, args.episodes, args.seeds)
    print("Paper Table II: one evader, three copies of the agent (SR = success rate, ± 1 s.e.)")
    print(format_table(rows))


if __name__ == "__main__":
    main()
