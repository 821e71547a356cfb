"""Wall time to competence: how long the Oracle trains until its learner's team pursues.

    python benchmarks/time_to_competence.py [--config configs/sp.yaml] [--set oracle.epochs=5]
        [--every 100000] [--episodes 500] [--max-env-steps 6000000] [--seed 0]
        [--success 0.85] [--collision 0.15]
        [--partners DIR] [--label NAME] [--out DIR] [--plot PNG]
    python benchmarks/time_to_competence.py --compare RUN.json ... --plot PNG

Self-play (the default, `configs/sp.yaml`: 3 pursuers vs 1 evader) trains in chunks of
`--every` env steps. After each chunk the clock stops and the learner, exported as every
other policy of the project is played (`MLPPolicy`, its deterministic action), is judged
offline on `--episodes` episodes (seeds no training evaluation uses) as a team of its own
copies. The run ends when the team is competent twice in a row (success ≥ 85 %, collision
≤ 15 %; the contract's 3 vs 2 bar is `--success 0.6 --collision 0.35`) or at `--max-env-steps`.
Only the Oracle's `train` counts as training time; the
judging, the exports and the start-up (Ray, the algorithm's build) do not, and are reported
apart.

`--partners DIR` trains a single learner instead, beside a fixed population: the learner
states an earlier run of this benchmark saved under DIR (every one it judged, or the last
`--partners-take` of them), drawn uniformly into the other seats. It is then judged beside
that population (its seat random, its teammates drawn per episode), and the chunks count
the learner's own transitions (`oracle.budget: learner_samples`).

Beside the training the same run measures two peers:
- the pure-sampling rate: the env runner sampling alone (`EnvRunner.sample`) with the final
  policy, env steps per second;
- a bare-torch PPO update of the same shape: the same actor and critic in plain torch, the
  same number of rows, minibatches and epochs as one of the run's PPO iterations, Adam and
  the global-norm clip; seconds per iteration beside the Oracle's own.

`benchmarks/calib.py` gives this machine's speed against the reference machine; the JSON
reports minutes as measured and scaled by it: by `--scale`, or by the mean of calib run
before and after the training (this machine's speed drifts by tens of percent within an
hour).
It prints one JSON line (last) and writes `<out>/<label>.json`, the checkpoints' RLlib
states (`<out>/<label>/*.npz`, plain arrays) and a plot of success and collision against
training wall time (`--plot`, default `<out>/<label>.png`).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SEED = 2_026_034
"""Judging seed of this benchmark: no training-time evaluation uses it."""
T975 = (float("nan"), 12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262)
"""Student's t quantile 0.975 by degrees of freedom (index), for intervals over seeds"""
COLORS = ("tab:gray", "tab:blue", "tab:green", "tab:orange", "tab:purple")
SUCCESS, COLLISION = 0.85, 0.15
"""Competence: a team at least this successful and at most this colliding"""


def calibrate() -> float:
    """This machine's scale to the reference machine (`benchmarks/calib.py`)."""
    calib = ROOT / "benchmarks" / "calib.py"
    out = subprocess.run([sys.executable, str(calib)], capture_output=True, text=True, check=True)
    return float(json.loads(out.stdout.strip().splitlines()[-1])["scale"])


def save_state(path: Path, state) -> None:
    """An RLlib module state (name → array) as a plain .npz, nothing pickled."""
    np.savez(path, **{k: np.asarray(v) for k, v in state.items()})


def load_state(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def bare_torch_update(config, rows: int, repeats: int = 2) -> float:
    """Seconds of one PPO iteration in plain torch: as many gradient steps as `rows` learner
    transitions make with the run's minibatch and epochs, each `update_step.bare_step` (the
    run's network, Beta head, clipped loss, value loss, clip and Adam)."""
    import math

    sys.path.insert(0, str(Path(__file__).parent))
    from update_step import bare_step

    o = config.oracle
    step = bare_step(config, config.env.layout.dim)
    steps = max(1, math.ceil(rows * o.epochs / o.minibatch))
    step()  # warm-up
    start = time.perf_counter()
    for _ in range(repeats * steps):
        step()
    return (time.perf_counter() - start) / repeats


def pure_sampling_rate(oracle, env_steps: int) -> float:
    """Env steps per second of the env runner sampling alone (no update, no sync)."""
    group = oracle.algo.env_runner_group
    local = group.num_remote_env_runners() == 0

    def sample(runner) -> tuple[int, float]:
        start = time.perf_counter()
        episodes = runner.sample(num_timesteps=env_steps, force_reset=True)
        return sum(e.env_steps() for e in episodes), time.perf_counter() - start

    results = group.foreach_env_runner(sample, local_env_runner=local)
    steps = sum(r[0] for r in results)
    seconds = max(r[1] for r in results)
    return steps / seconds


class Judge:
    """Plays an exported learner: as a team of its copies, or beside a fixed population."""

    def __init__(self, config, episodes: int, partners: list | None = None):
        self.config, self.episodes, self.partners = config, episodes, partners

    def __call__(self, export) -> dict[str, float]:
        from hola_ray.evaluation.rollout import rollout
        from hola_ray.evaluation.teams import play
        from hola_ray.policies.learned import MLPPolicy

        env = self.config.env
        learner = MLPPolicy(env, export, name="learner")
        if self.partners is None:
            s = rollout(env, [learner] * env.n_pursuers, self.episodes, seed=SEED).summary()
            return {"success": s["success"], "collision": s["collision"], "length": s["length"]}
        record = play(learner, self.partners, env, self.episodes, [SEED])
        return {
            "success": float(np.mean(record["success"])),
            "collision": float(np.mean(record["collision"])),
            "length": float(np.mean(record["length"])),
            "own_crash": float(np.mean(record["learner_crash"])),
        }


def competent(
    row: dict[str, float], success: float = SUCCESS, collision: float = COLLISION
) -> bool:
    return row["success"] >= success and row["collision"] <= collision


def plot(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    minutes = [r["train_s"] / 60 for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(minutes, [100 * r["success"] for r in rows], "o-", label="success")
    ax.plot(minutes, [100 * r["collision"] for r in rows], "s-", label="collision")
    ax.axhline(100 * SUCCESS, color="C0", ls=":", lw=1)
    ax.axhline(100 * COLLISION, color="C1", ls=":", lw=1)
    ax.set_xlabel("training wall time (min, this machine)")
    ax.set_ylabel("% of episodes")
    ax.set_ylim(0, 100)
    ax.set_title(title, fontsize=9)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def compare(paths: list[Path], out: Path) -> dict:
    """One figure and one summary of several runs' JSON (before and after, per seed): each
    run's success and collision against training time in reference-machine minutes; runs
    labelled `<group>-s<seed>` are grouped, with the mean and a t-interval of their
    reference minutes to competence (a run never competent counts as missing)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [json.loads(p.read_text()) for p in paths]
    groups: dict[str, list[dict]] = {}
    for r in runs:
        groups.setdefault(r["label"].rsplit("-s", 1)[0], []).append(r)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharex=True)
    summary = {}
    for color, (group, members) in zip(COLORS, groups.items(), strict=False):
        for k, r in enumerate(members):
            minutes = [row["train_s"] * r["scale"] / 60 for row in r["judged"]]
            for ax, key in zip(axes, ("success", "collision"), strict=True):
                ax.plot(
                    minutes,
                    [100 * row[key] for row in r["judged"]],
                    color=color,
                    lw=1,
                    alpha=0.8,
                    label=group if k == 0 else None,
                )
        reached = [r["minutes_to_competence"]["reference"] for r in members]
        done = [m for m in reached if m is not None]
        mean = float(np.mean(done)) if done else None
        half = (
            float(T975[len(done) - 1] * np.std(done, ddof=1) / np.sqrt(len(done)))
            if 1 < len(done) <= len(T975)
            else None
        )
        summary[group] = {
            "seeds": [r["seed"] for r in members],
            "reference_minutes": reached,
            "mean": None if mean is None else round(mean, 2),
            "interval95": None if half is None else [round(mean - half, 2), round(mean + half, 2)],
            "env_steps": [r["env_steps_to_competence"] for r in members],
            "learner_samples": [r["learner_samples_to_competence"] for r in members],
            "measured_minutes": [r["minutes_to_competence"]["measured"] for r in members],
            "scale": [r["scale"] for r in members],
        }
    for ax, key, line in zip(axes, ("success", "collision"), (SUCCESS, COLLISION), strict=True):
        ax.axhline(100 * line, color="k", ls=":", lw=1)
        ax.set(xlabel="training time (min, reference machine)", ylabel=f"{key} (%)", ylim=(0, 100))
        ax.legend(fontsize=8)
    fig.suptitle(
        "self-play 3 vs 1, judged as 3 copies every ~100k env steps (500 episodes)", fontsize=9
    )
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return summary


def partner_population(directory: Path, take: int, config):
    """(module states, exported policies) of the learner states an earlier run saved."""
    from hola_ray.policies.learned import MLPPolicy

    files = sorted(directory.glob("*.npz"))
    if not files:
        raise SystemExit(f"{directory}: no saved learner states (*.npz)")
    files = files[-take:] if take else files
    states = [load_state(f) for f in files]
    policies = [
        MLPPolicy(config.env, config.export(s), name=f.stem)
        for s, f in zip(states, files, strict=True)
    ]
    return states, policies


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "sp.yaml")
    parser.add_argument("--set", action="append", default=[], dest="sets")
    parser.add_argument("--every", type=int, default=100_000)
    parser.add_argument("--episodes", type=int, default=500)
    parser.add_argument("--max-env-steps", type=float, default=6e6)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--partners", type=Path, default=None)
    parser.add_argument("--partners-take", type=int, default=3)
    parser.add_argument("--full", action="store_true", help="train on to --max-env-steps")
    parser.add_argument("--label", default=None)
    parser.add_argument("--out", type=Path, default=ROOT / "runs" / "time_to_competence")
    parser.add_argument("--plot", type=Path, default=None)
    parser.add_argument("--scale", type=float, default=None)
    parser.add_argument("--sample-steps", type=int, default=50_000)
    parser.add_argument(
        "--success", type=float, default=SUCCESS, help="competence: at least this success"
    )
    parser.add_argument(
        "--collision", type=float, default=COLLISION, help="and at most this collision"
    )
    parser.add_argument(
        "--compare",
        type=Path,
        nargs="+",
        default=None,
        help="draw these runs' JSON together (to --plot) and print their summary; no training",
    )
    args = parser.parse_args(argv)
    if args.compare:
        summary = compare(args.compare, args.plot or args.out / "compare.png")
        print(json.dumps(summary), flush=True)
        return summary

    import ray
    import torch

    from hola_ray.commands.run import read_config
    from hola_ray.config.oracle import Seating
    from hola_ray.oracle import LEARNER, Oracle
    from hola_ray.oracle.mapping import member_module
    from hola_ray.process import init_ray

    sets = [*args.sets, f"seed={args.seed}"]
    if args.partners is not None:
        sets.append("oracle.budget=learner_samples")
    config = read_config(args.config, sets)
    label = args.label or f"{config.method}-s{args.seed}"
    ckpt_dir = args.out / label
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    scales = [args.scale if args.scale is not None else calibrate()]

    init_ray("time_to_competence", num_cpus=2)
    start = time.perf_counter()
    partners = None
    if args.partners is None:
        seating = Seating()
    else:
        states, partners = partner_population(args.partners, args.partners_take, config)
        seating = Seating(partners=len(states))
    oracle = Oracle(config.env, config.oracle, seating, config.seed)
    if partners is not None:
        oracle.set_partners({member_module(i): s for i, s in enumerate(states)})
        oracle.set_phi({member_module(i): 1.0 / len(states) for i in range(len(states))})
    setup_s = time.perf_counter() - start
    judge = Judge(config, args.episodes, partners)

    rows: list[dict] = []
    train_s = sample_s = learn_s = judge_s = 0.0
    env_steps = samples = iterations = 0
    reached = None
    while env_steps < args.max_env_steps:
        t0 = time.perf_counter()
        stats = oracle.train(args.every, desc=label, progress=False)
        train_s += time.perf_counter() - t0
        sample_s += stats.sample_s
        learn_s += stats.learn_s
        env_steps += stats.env_steps
        samples += stats.learner_samples
        iterations += stats.iterations
        t0 = time.perf_counter()
        state = oracle.weights([LEARNER])[LEARNER]
        save_state(ckpt_dir / f"{env_steps:09d}.npz", state)
        row = {
            "env_steps": env_steps,
            "learner_samples": samples,
            "train_s": round(train_s, 2),
            **{k: round(v, 4) for k, v in judge(config.export(state)).items() if v is not None},
            "std_median": round(stats.spread.get("std_median", float("nan")), 4),
        }
        judge_s += time.perf_counter() - t0
        rows.append(row)
        print(json.dumps(row), flush=True)
        bar = (args.success, args.collision)
        if (
            reached is None
            and len(rows) >= 2
            and competent(rows[-1], *bar)
            and competent(rows[-2], *bar)
        ):
            reached = rows[-1]
            if not args.full:
                break

    rate = pure_sampling_rate(oracle, args.sample_steps)
    rows_per_iteration = samples / max(iterations, 1)
    bare = bare_torch_update(config, int(rows_per_iteration))
    oracle.stop()
    ray.shutdown()
    if args.scale is None:  # the machine's speed drifts: calibrate after the run too
        scales.append(calibrate())
    scale = float(np.mean(scales))

    def minutes(seconds: float | None) -> dict:
        if seconds is None:
            return {"measured": None, "reference": None}
        return {"measured": round(seconds / 60, 2), "reference": round(seconds * scale / 60, 2)}

    result = {
        "label": label,
        "config": str(
            args.config.relative_to(ROOT) if args.config.is_relative_to(ROOT) else args.config
        ),
        "sets": args.sets,
        "seed": args.seed,
        "mode": "self-play" if partners is None else f"single learner, {len(partners)} partners",
        "competent": reached is not None,
        "competence": {"success": args.success, "collision": args.collision},
        "env_steps_to_competence": reached["env_steps"] if reached else None,
        "learner_samples_to_competence": reached["learner_samples"] if reached else None,
        "minutes_to_competence": minutes(reached["train_s"] if reached else None),
        "at_competence": {k: reached[k] for k in ("success", "collision")} if reached else None,
        "scale": round(scale, 3),
        "scales": scales,
        "train_s": round(train_s, 2),
        "oracle_sample_s": round(sample_s, 2),
        "oracle_learn_s": round(learn_s, 2),
        "learn_share": round(learn_s / max(train_s, 1e-9), 3),
        "env_steps": env_steps,
        "learner_samples": samples,
        "oracle_env_steps_per_s": round(env_steps / max(train_s, 1e-9), 1),
        "learner_samples_per_s": round(samples / max(train_s, 1e-9), 1),
        "pure_sampling_env_steps_per_s": round(rate, 1),
        "update_s_per_iteration": round(learn_s / max(iterations, 1), 3),
        "bare_torch_update_s_per_iteration": round(bare, 3),
        "rows_per_iteration": int(rows_per_iteration),
        "torch_threads": torch.get_num_threads(),
        "setup_s": round(setup_s, 1),
        "judge_s": round(judge_s, 1),
        "judged": rows,
    }
    (args.out / f"{label}.json").write_text(json.dumps(result, indent=1))
    title = f"{label}: {result['mode']}, " + (
        f"competent at {reached['env_steps'] / 1e6:.2f} M env steps, "
        f"{result['minutes_to_competence']['measured']} min here "
        f"({result['minutes_to_competence']['reference']} reference)"
        if reached
        else "not competent"
    )
    plot(rows, args.plot or args.out / f"{label}.png", title)
    print(json.dumps({k: v for k, v in result.items() if k != "judged"}), flush=True)
    return result


if __name__ == "__main__":
    main()
