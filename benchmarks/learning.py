"""Learning curves of the policies the project plays: the exported deterministic learner,
measured in `rollout` (never RLlib's training metrics).

    python benchmarks/learning.py [--sp-run DIR] [--default-run DIR] [--sp-3v2]
                                  [--skip-sp] [--skip-default] [--episodes 500] [--out DIR]

1. Self-play (`configs/sp.yaml`, 3 pursuers vs 1 evader): every generation's learner as
   three copies, 500 episodes on seeds no training evaluation used: success, collision,
   length, and the policy's spread (median std on the reference observations).
   `--sp-3v2` does the same for 3 vs 2 (`configs/sp.yaml` with two evaders).
2. The embedded default HOLA run (`python -m hola_ray.run`): every generation's learner in
   a random seat with Greedy and VICSEK as teammates (in random seats), 500 episodes;
   beside it, in the same run and on the same seeds, a Greedy in the learner's seat.

Without `--sp-run` / `--default-run` it trains those runs first (about 30 and 10 minutes
on 2 CPUs) under `--out`. It writes `learning.png` and `learning.json` there and prints
as its last line one JSON object with the final figures.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.probe import reference_observations
from hola_ray.evaluation.rollout import rollout
from hola_ray.methods.config import RunConfig
from hola_ray.policies import Greedy, MLPPolicy, Vicsek
from hola_ray.population.rundir import RunDir

ROOT = Path(__file__).resolve().parents[1]
SEED = 2_026_000
"""Evaluation seed of this benchmark: no training-time evaluation uses it."""


def train(config: Path | None, out: Path, overrides: dict | None = None) -> Path:
    """Run the main job (a fresh subprocess and local Ray) and return its run directory."""
    if out.exists() and RunDir(out).completed():
        print(f"reusing {out}", flush=True)
        return out
    args = [sys.executable, "-m", "hola_ray.run", "--out", str(out), "--no-dashboard", "--quiet"]
    if overrides is not None:
        data = yaml.safe_load(config.read_text()) if config else {}
        data.update(overrides)
        config = out.parent / f"{out.name}.yaml"
        config.write_text(yaml.safe_dump(data))
    if config is not None:
        args += ["--config", str(config)]
    print("training:", " ".join(args[1:]), flush=True)
    start = time.perf_counter()
    subprocess.run(args, check=True, cwd=ROOT)
    print(f"trained in {(time.perf_counter() - start) / 60:.1f} min", flush=True)
    return out


def generation_policies(run_dir: Path):
    """(generation, env steps, MLPPolicy) of every completed generation's learner."""
    run = RunDir(run_dir)
    config = RunConfig.from_yaml(run.config)
    for g in run.completed():
        state = run.load_learner_state(g)
        if state is None:
            continue
        steps = int(run.read_json(g, "metrics.json")["env_steps"])
        yield g, steps, MLPPolicy(config.env, config.export(state), name=f"gen{g}")


def measure(config: PursuitConfig, policies, episodes: int, assignment=None) -> dict:
    s = rollout(config, policies, episodes, assignment=assignment, seed=SEED).summary()
    return {k: round(s[k], 4) for k in ("success", "collision", "length")} | {
        f"{k}_se": round(s[f"{k}_se"], 4) for k in ("success", "collision", "length")
    }


def self_play_curve(run_dir: Path, episodes: int) -> list[dict]:
    config = RunConfig.from_yaml(RunDir(run_dir).config).env
    obs = reference_observations(config)
    rows = []
    for g, steps, policy in generation_policies(run_dir):
        row = {"generation": g, "env_steps": steps, **measure(config, [policy] * 3, episodes)}
        row["std_median"] = round(policy.spread(obs)["std_median"], 4)
        rows.append(row)
        print(f"  sp gen {g} ({steps:,} steps): {_fmt(row)}", flush=True)
    return rows


def seated_assignment(episodes: int, rng: np.random.Generator) -> np.ndarray:
    """[episodes, 3]: candidate 0 (the seat under test) in a random slot, Greedy (1) and
    VICSEK (2) in the other two in random order."""
    return np.stack([rng.permutation(3) for _ in range(episodes)])


def seated_curve(run_dir: Path, episodes: int) -> tuple[list[dict], dict]:
    config = RunConfig.from_yaml(RunDir(run_dir).config).env
    if config.n_pursuers != 3:
        raise SystemExit(f"{run_dir}: the seated test needs 3 pursuers, not {config.n_pursuers}")
    assignment = seated_assignment(episodes, np.random.default_rng(SEED))
    greedy, vicsek = Greedy(config), Vicsek(config)
    reference = measure(config, [Greedy(config), greedy, vicsek], episodes, assignment)
    print(f"  Greedy in the seat: {_fmt(reference)}", flush=True)
    rows = []
    for g, steps, policy in generation_policies(run_dir):
        row = {"generation": g, "env_steps": steps}
        row |= measure(config, [policy, greedy, vicsek], episodes, assignment)
        rows.append(row)
        print(f"  default gen {g}: {_fmt(row)}", flush=True)
    return rows, reference


def _fmt(row: dict) -> str:
    return (
        f"success {row['success']:.1%} ± {row['success_se']:.1%}, "
        f"collision {row['collision']:.1%}, length {row['length']:.0f}"
    )


def plot(path: Path, curves: dict[str, list[dict]], reference: dict | None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [k for k in ("sp_3v1", "sp_3v2", "default") if curves.get(k)]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4), squeeze=False)
    titles = {
        "sp_3v1": "self-play, 3 vs 1: three copies",
        "sp_3v2": "self-play, 3 vs 2: three copies",
        "default": "default HOLA run: learner + Greedy + VICSEK",
    }
    for ax, key in zip(axes[0], panels, strict=True):
        rows = curves[key]
        x = np.array([r["env_steps"] for r in rows]) / 1e6
        for name, color in (("success", "tab:green"), ("collision", "tab:red")):
            y = np.array([r[name] for r in rows])
            se = np.array([r[f"{name}_se"] for r in rows])
            ax.errorbar(x, y, yerr=se, marker="o", ms=3, color=color, label=name, capsize=2)
        if key == "default" and reference:
            ax.axhline(reference["success"], color="tab:green", ls=":", label="Greedy: success")
            ax.axhline(reference["collision"], color="tab:red", ls=":", label="Greedy: collision")
        if key.startswith("sp"):
            ax.plot(x, [r["std_median"] for r in rows], "k--", lw=1, label="policy std (median)")
        ax.set_ylim(0, 1)
        ax.set_xlabel("env steps (M)")
        ax.set_title(titles[key], fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle("the exported deterministic learner in rollout (500 episodes per point)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("runs/learning"))
    parser.add_argument("--sp-run", type=Path, help="an existing configs/sp.yaml run directory")
    parser.add_argument("--default-run", type=Path, help="an existing default run directory")
    parser.add_argument("--sp-3v2", action="store_true", help="also self-play 3 vs 2")
    parser.add_argument("--skip-sp", action="store_true")
    parser.add_argument("--skip-default", action="store_true")
    parser.add_argument("--episodes", type=int, default=500)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    sp_yaml = ROOT / "configs" / "sp.yaml"

    curves: dict[str, list[dict]] = {}
    reference = None
    summary: dict[str, float] = {}
    if not args.skip_sp:
        run = args.sp_run or train(sp_yaml, args.out / "sp_3v1")
        print(f"self-play 3 vs 1 ({run}):", flush=True)
        curves["sp_3v1"] = rows = self_play_curve(run, args.episodes)
        best = max(rows, key=lambda r: (r["success"], -r["collision"]))
        summary |= _final("sp_3v1", rows[-1]) | {
            "sp_3v1_best_success": best["success"],
            "sp_3v1_best_collision": best["collision"],
            "sp_3v1_best_generation": best["generation"],
            "sp_3v1_last_minus_best_success": round(rows[-1]["success"] - best["success"], 4),
        }
    if args.sp_3v2:
        env = yaml.safe_load(sp_yaml.read_text())["env"] | {"n_evaders": 2}
        run = train(sp_yaml, args.out / "sp_3v2", overrides={"env": env})
        print(f"self-play 3 vs 2 ({run}):", flush=True)
        curves["sp_3v2"] = rows = self_play_curve(run, args.episodes)
        summary |= _final("sp_3v2", rows[-1])
    if not args.skip_default:
        run = args.default_run or train(None, args.out / "default")
        print(f"default HOLA run ({run}), seated with Greedy + VICSEK:", flush=True)
        rows, reference = seated_curve(run, args.episodes)
        curves["default"] = rows
        last = rows[-1]
        summary |= {
            "default_learner_with_greedy_vicsek_success": last["success"],
            "default_learner_with_greedy_vicsek_collision": last["collision"],
            "default_learner_with_greedy_vicsek_length": last["length"],
            "greedy_with_greedy_vicsek_success": reference["success"],
            "greedy_with_greedy_vicsek_collision": reference["collision"],
            "greedy_with_greedy_vicsek_length": reference["length"],
        }
    summary["episodes_per_point"] = args.episodes
    (args.out / "learning.json").write_text(
        json.dumps({"curves": curves, "greedy_reference": reference, "summary": summary}, indent=1)
    )
    if curves:
        plot(args.out / "learning.png", curves, reference)
        print(f"wrote {args.out / 'learning.png'} and {args.out / 'learning.json'}")
    print(json.dumps(summary))
    return 0


def _final(prefix: str, row: dict) -> dict:
    return {
        f"{prefix}_success": row["success"],
        f"{prefix}_collision": row["collision"],
        f"{prefix}_length": row["length"],
        f"{prefix}_env_steps": row["env_steps"],
        f"{prefix}_std_median": row["std_median"],
    }


if __name__ == "__main__":
    sys.exit(main())
