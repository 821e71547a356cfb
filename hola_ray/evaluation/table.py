"""Paper Table II: one evader, three copies of an agent, 50 episodes per seed.

`python -m hola_ray.evaluation.table [--episodes 50] [--seeds 0 1 2] [--json]` prints the
six rows beside the paper's figures: Greedy and VICSEK from their code, PPO (1), (2) and
D3QN-G (1), (2) from the committed pools (`hola_ray.evaluation.pools`, hashes verified). A row whose
pool is not built says so. With `--json` the last line is
`{"rows": {"PPO (1)": {"success": …, "length": …, "collision": …}, …}}`.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence

import numpy as np

from hola_ray.cli import OneLineParser, fail
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.metrics import TEAM
from hola_ray.evaluation.pools import PoolError, load_pool
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.stats import mean_and_se
from hola_ray.policies.base import Policy
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
"""Registry name → Table II row, for the hand-written agents."""

POOLED = {
    "PPO (1)": ("hot", "ppo-1"),
    "PPO (2)": ("hot", "ppo-2"),
    "D3QN-G (1)": ("het", "d3qn-g-1"),
    "D3QN-G (2)": ("het", "d3qn-g-2"),
}
"""Table II row → (pool, member id), for the trained agents."""


def table_scenario(config: PursuitConfig | None = None) -> PursuitConfig:
    """Table II's scenario: the arena with one evader."""
    return dataclasses.replace(config or PursuitConfig(), n_evaders=1)


def measure(
    policy: Policy, config: PursuitConfig, episodes: int, seeds: Sequence[int]
) -> dict[str, float]:
    """Three (n_p) copies of `policy`, `episodes` per seed, pooled: success, length and
    collision (every `TEAM` metric) with their standard errors."""
    runs = [rollout(config, [policy] * config.n_pursuers, episodes, seed=s) for s in seeds]
    out: dict[str, float] = {}
    for name in (m.field for m in TEAM):
        mean, se = mean_and_se(np.concatenate([getattr(r, name) for r in runs]))
        out[name], out[f"{name}_se"] = mean, se
    out["episodes"] = float(len(seeds) * episodes)
    return out


def _row(label: str, figures: dict[str, float]) -> dict[str, float | str]:
    paper_sr, paper_ael = PAPER_TABLE_II.get(label, (float("nan"), float("nan")))
    return {
        "agent": label,
        "sr": figures["success"],
        "sr_se": figures["success_se"],
        "ael": figures["length"],
        "ael_se": figures["length_se"],
        "collision": figures["collision"],
        "collision_se": figures["collision_se"],
        "paper_sr": paper_sr,
        "paper_ael": paper_ael,
        "episodes": figures["episodes"],
    }


def table_rows(
    agents: Sequence[str] = tuple(AVAILABLE),
    episodes: int = 50,
    seeds: Sequence[int] = (0, 1, 2),
    config: PursuitConfig | None = None,
) -> list[dict[str, float | str]]:
    """Rows for registry agents (hand-written, APF-A pairs …), three copies each."""
    config = table_scenario(config)
    rows = []
    for name in agents:
        policy = make_policy(name, config)
        label = AVAILABLE.get(name, policy.name)
        rows.append(_row(label, measure(policy, config, episodes, seeds)))
    return rows


def paper_rows(
    episodes: int = 50, seeds: Sequence[int] = (0, 1, 2)
) -> tuple[list[dict[str, float | str]], dict[str, str]]:
    """All six of the paper's rows that can be measured here, and why the others cannot
    (row → the pool error)."""
    config = table_scenario()
    measured: dict[str, dict[str, float | str]] = {
        r["agent"]: r for r in table_rows(list(AVAILABLE), episodes, seeds, config)
    }
    missing: dict[str, str] = {}
    pools: dict[str, dict[str, Policy] | PoolError] = {}
    for label, (pool, mid) in POOLED.items():
        if pool not in pools:
            try:
                pools[pool] = load_pool(pool, config)
            except PoolError as err:
                pools[pool] = err
        members = pools[pool]
        if isinstance(members, PoolError):
            missing[label] = str(members)
            continue
        measured[label] = _row(label, measure(members[mid], config, episodes, seeds))
    rows = [measured[k] for k in PAPER_TABLE_II if k in measured]
    return rows, missing


def format_table(rows: list[dict[str, float | str]], missing: dict[str, str] | None = None) -> str:
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
    for label, why in (missing or {}).items():
        lines.append(f"{label:<11} not measured: {why}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """The command; 0, or 2 after one line on stderr for a bad input."""
    parser = OneLineParser(
        prog="python -m hola_ray.evaluation.table", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--episodes", type=int, default=50, help="episodes per seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="run seeds")
    parser.add_argument("--json", action="store_true", help="last line: the rows as JSON")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        return fail(f"--episodes must be at least 1, got {args.episodes}")
    rows, missing = paper_rows(args.episodes, args.seeds)
    print("Paper Table II: one evader, three copies of the agent (SR = success rate, ± 1 s.e.)")
    print(format_table(rows, missing))
    if args.json:
        out = {
            "rows": {
                r["agent"]: {
                    "success": round(float(r["sr"]), 4),
                    "success_se": round(float(r["sr_se"]), 4),
                    "length": round(float(r["ael"]), 2),
                    "length_se": round(float(r["ael_se"]), 2),
                    "collision": round(float(r["collision"]), 4),
                    "collision_se": round(float(r["collision_se"]), 4),
                    "paper_success": r["paper_sr"],
                    "paper_length": r["paper_ael"],
                }
                for r in rows
            }
        }
        print(json.dumps(out))
    return 0


def script() -> None:
    """`hola-table` (`[project.scripts]`) and `python -m`: `main`, then a quick exit."""
    from hola_ray.process import leave, pause_collector

    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
