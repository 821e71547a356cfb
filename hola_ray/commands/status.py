"""Where a run stands: `python -m hola_ray status RUN_DIR [--live] [--plot]`; given an
experiment's directory, where each of its trials stands (`hola_ray.experiment.progress`).

Reads the run directory: last completed generation, population with slot, η, φ and node
value, the last metrics row. With --live it also asks the running
coordinator actor for its view, which includes the phase of the generation in progress.
--plot writes RUN_DIR/progress.png: success, collision and return per generation (accepted
learners and the best generation marked), φ entropy, and the policy's spread per PPO
iteration.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
from pathlib import Path
from typing import Any

from hola_ray.evaluation.metrics import TEAM
from hola_ray.methods.config import RunConfig
from hola_ray.population.rundir import RunDir

_METRICS = (
    "env_steps",
    "learner_samples",
    "val_success",
    "val_collision",
    "val_learner_crash",
    "members_success",
    "members_success_min",
    "members_crash",
    "population_team_success",
    "population_team_crash",
    *(f"learner_{m.name}" for m in TEAM),
    "std_median",
    "clipped",
    "accepted",
    "rank",
    "phi_entropy",
    "phi_tv",
    "phi_tv_uniform",
    "oracle_s",
    "oracle_env_steps_per_s",
    "grapher_s",
    "population_success",
)


def disk_view(run_dir: Path) -> dict[str, Any]:
    """The status of a run from its directory alone."""
    run = RunDir(run_dir)
    if not run.config.is_file():
        raise FileNotFoundError(f"{run_dir} is not a run directory (no config.yaml)")
    last = run.last_completed()
    view: dict[str, Any] = {"run_dir": str(run_dir), "generation": last, "members": []}
    if last is None:
        return view
    state = run.read_json(last, "state.json")
    phi = run.read_json(last, "phi.json")
    eta = run.read_json(last, "eta.json")
    slots = state["population"]["slots"]
    view["members"] = [
        {"node": int(node), "slot": slot, "eta": eta.get(node), "phi": phi.get(node)}
        for node, slot in slots.items()
    ]
    view["decision"] = state.get("decision")
    view["last_metrics"] = run.metrics(last)
    return view


def live_view(run_dir: Path) -> dict[str, Any] | None:
    """The running coordinator's view, or None when no run of that name is live."""
    import ray

    from hola_ray.population.coordinator import coordinator_name
    from hola_ray.process import NAMESPACE

    ray.init(
        address=os.environ.get("RAY_ADDRESS", "auto"), namespace=NAMESPACE, log_to_driver=False
    )
    try:
        actor = ray.get_actor(coordinator_name(str(run_dir)), namespace=NAMESPACE)
    except ValueError:
        return None
    return ray.get(actor.view.remote(), timeout=30)


def format_view(view: dict[str, Any], source: str) -> str:
    lines = [f"{source}: {view['run_dir']}", f"  last completed generation: {view['generation']}"]
    if "phase" in view:
        lines.append(f"  phase now: {view['phase']}")
    if view.get("members"):
        lines.append(f"  {'node':>5} {'slot':>4} {'eta':>6} {'phi':>6}")
        for m in view["members"]:
            eta = "-" if m["eta"] is None else f"{m['eta']:.3f}"
            phi = "-" if m["phi"] is None else f"{m['phi']:.3f}"
            lines.append(f"  {m['node']:>5} {m['slot']:>4} {eta:>6} {phi:>6}")
    metrics = view.get("last_metrics") or {}
    shown = {k: metrics[k] for k in _METRICS if k in metrics and metrics[k] != ""}
    if shown:
        lines.append("  last metrics: " + ", ".join(f"{k}={_fmt(v)}" for k, v in shown.items()))
    return "\n".join(lines)


def _fmt(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def plot_progress(run_dir: Path) -> Path:
    """RUN_DIR/progress.png. Per generation: success, collision and team return (± s.e.)
    of G_0 (generation 0, the pre-trained population), of each generation's learner as
    it was judged (with the population's members, or in self-play as three copies) and of
    the learner with the validation teammates (with its own crash rate), the accepted
    learners and the best generation (on the validation curve, its rule) marked; φ entropy
    (self-play: episode length). Per PPO iteration
    (iterations.csv): the trained policy's median std and its clipped fraction. Against the
    run's cumulative wall time: success and collision; per generation, the Oracle's speed.
    Where the time went (`hola_ray.clock`): each row's seconds by phase, and the run's
    share of each phase."""
    from matplotlib.figure import Figure

    run = RunDir(run_dir)
    rows = list(csv.DictReader(run.metrics_csv.open()))
    best = run.best_generation()
    fig = Figure(figsize=(21, 7.6))  # no pyplot, no global backend switched
    axes = fig.subplots(2, 5)
    for ax, name, label in (
        (axes[0, 0], "success", "success rate"),
        (axes[0, 1], "collision", "collision rate"),
        (axes[0, 2], "return", "team return"),
    ):
        _outcome_panel(ax, rows, best, name, label)
    axes[0, 0].set_ylim(0, 1)
    axes[0, 1].set_ylim(0, 1)
    iterations = (
        list(csv.DictReader(run.iterations_csv.open())) if run.iterations_csv.is_file() else []
    )
    _iteration_panels(iterations, axes[1, 0], axes[1, 1])
    if RunConfig.from_yaml(run.config).strategy.trains_alone():  # no population, no φ
        _length_panel(rows, axes[1, 2])
    else:
        _phi_panel(rows, axes[1, 2])
    _wall_time_panels(rows, axes[0, 3], axes[1, 3])
    _time_panels(rows, axes[0, 4], axes[1, 4])
    fig.suptitle(run_dir.name, fontsize=9)
    fig.tight_layout()
    out = run_dir / "progress.png"
    fig.savefig(out, dpi=120)
    return out


def _series(
    rows: list[dict[str, str]], prefix: str, name: str
) -> tuple[list[int], list[float], list[float]]:
    """(generations, means, standard errors) of `<prefix>_<name>` over the rows that hold
    it: a generation without the figure (no validation, no G_0 row) is left out, not 0."""
    have = [r for r in rows if r.get(f"{prefix}_{name}")]
    return (
        [int(r["generation"]) for r in have],
        [float(r[f"{prefix}_{name}"]) for r in have],
        [float(r[f"{prefix}_{name}_se"]) for r in have],
    )


def _outcome_panel(ax, rows: list[dict[str, str]], best: int | None, name: str, label: str) -> None:
    """One outcome (`success`, `collision` or `return`) per generation: G_0, the learner as
    judged and the learner with the validation teammates (on `collision`, also its own
    crash rate), with the accepted learners and best.pt marked."""
    for prefix, text, style in (
        ("population", "G_0 (pre-trained)", "s"),
        ("learner", "learner as judged", "o"),
        ("val", "learner with the validation teammates", "^"),
    ):
        gens, mean, se = _series(rows, prefix, name)
        if gens:
            ax.errorbar(gens, mean, yerr=se, marker=style, capsize=3, label=text)
    if name == "collision":
        gens, mean, se = _series(rows, "val", "learner_crash")
        if gens:
            ax.errorbar(gens, mean, yerr=se, marker="v", capsize=3, label="its own crash")
    _mark_choices(ax, rows, best, name)
    ax.set(xlabel="generation", ylabel=label)
    ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)


def _mark_choices(ax, rows: list[dict[str, str]], best: int | None, name: str) -> None:
    """Ring the accepted learners on the curve they were judged on, and star the best
    generation on the curve best.pt is chosen on: the validation one where there is one
    (its rule), else the learner's."""
    gens, mean, _ = _series(rows, "learner", name)
    value = dict(zip(gens, mean, strict=True))
    gens, mean, _ = _series(rows, "val", name)
    chosen_on = dict(zip(gens, mean, strict=True)) or value  # best.pt's rule
    accepted = [int(r["generation"]) for r in rows if r.get("accepted") == "1"]
    shown = [g for g in accepted if g in value]
    if shown:
        ax.scatter(
            shown,
            [value[g] for g in shown],
            s=110,
            facecolors="none",
            edgecolors="tab:green",
            linewidths=1.5,
            label="accepted",
            zorder=3,
        )
    if best is not None and best in chosen_on:
        ax.scatter(
            [best],
            [chosen_on[best]],
            marker="*",
            s=160,
            color="gold",
            edgecolors="k",
            label="best.pt",
            zorder=4,
        )


def _iteration_panels(iterations: list[dict[str, str]], std, clipped) -> None:
    """Per PPO iteration (iterations.csv), pre-training and the learners apart: the trained
    policy's median std, and the share of its sampled actions at the Box's edge."""
    for ax, key, label in (
        (std, "std_median", "policy std, median (RLlib's [−1, 1] units)"),
        (clipped, "clipped", "sampled actions at the Box's edge"),
    ):
        for pretrain in (True, False):
            its = [r for r in iterations if (r["generation"] == "0") == pretrain and r.get(key)]
            if its:
                ax.plot(
                    range(len(its)),
                    [float(r[key]) for r in its],
                    lw=1,
                    label="pre-training" if pretrain else "learner",
                )
        ax.set(xlabel="PPO iteration", ylabel=label)
        if iterations:
            ax.legend(fontsize=7)


def _length_panel(rows: list[dict[str, str]], ax) -> None:
    """Self-play's stand-in for the φ panel (no population, no φ): the learner's episode
    length per generation."""
    gens, mean, se = _series(rows, "learner", "length")
    ax.errorbar(gens, mean, yerr=se, marker="o", capsize=3)
    ax.set(xlabel="generation", ylabel="episode length (steps)")


def _phi_panel(rows: list[dict[str, str]], ax) -> None:
    """φ's entropy per generation and, where the run logs it, φ's distance from the rival
    rule's (`Method.rival`) on its own axis, the 0.01 line marked."""
    every = [int(r["generation"]) for r in rows]
    ax.plot(every, [float(r["phi_entropy"]) for r in rows], marker="o")
    ax.set(xlabel="generation", ylabel="φ entropy (nats)")
    parted = [(int(r["generation"]), float(r["phi_tv"])) for r in rows if r.get("phi_tv")]
    if parted:
        tv = ax.twinx()
        tv.plot(*zip(*parted, strict=True), color="tab:red", marker=".", lw=1)
        tv.axhline(0.01, color="tab:red", ls=":", lw=0.8)
        tv.set_ylabel("φ's distance from the rival rule's (TV)", color="tab:red")


def _wall_time_panels(rows: list[dict[str, str]], figures, speed) -> None:
    """Success and collision against the run's cumulative wall time (`cumulative_wall_s`),
    and each generation's Oracle speed (env steps per second of training)."""
    timed = [r for r in rows if r.get("cumulative_wall_s")]
    for prefix, style in (("learner", "o"), ("val", "^"), ("population", "s")):
        for name, color in (("success", "tab:blue"), ("collision", "tab:red")):
            have = [r for r in timed if r.get(f"{prefix}_{name}")]
            if have:
                figures.plot(
                    [float(r["cumulative_wall_s"]) / 60 for r in have],
                    [float(r[f"{prefix}_{name}"]) for r in have],
                    marker=style,
                    color=color,
                    ls="-" if prefix != "val" else ":",
                    label=f"{prefix} {name}",
                )
    figures.set(xlabel="wall time, cumulative (min)", ylabel="rate", ylim=(0, 1))
    if timed:
        figures.legend(fontsize=6)
    paced = [r for r in rows if r.get("oracle_env_steps_per_s")]
    speed.plot(
        [int(r["generation"]) for r in paced],
        [float(r["oracle_env_steps_per_s"]) for r in paced],
        marker="o",
    )
    speed.set(xlabel="generation", ylabel="Oracle env steps / s of training")


def _time_panels(rows: list[dict[str, str]], per_row, shares) -> None:
    """Where the time went: each metrics row's seconds stacked by phase (`time_<phase>_s`,
    `hola_ray.clock.PHASES`), and each phase's share of all rows' time."""
    from hola_ray.clock import NAMES, column

    timed = [r for r in rows if r.get(column("other"))]
    phases = [p for p in NAMES if any(r.get(column(p)) for r in timed)]
    gens = [int(r["generation"]) for r in timed]
    bottom = [0.0] * len(timed)
    totals = {}
    colors = dict(zip(NAMES, _PHASE_COLORS, strict=False))
    for phase in phases:
        seconds = [float(r.get(column(phase)) or 0.0) for r in timed]
        per_row.bar(gens, seconds, bottom=bottom, label=phase, color=colors[phase])
        bottom = [b + x for b, x in zip(bottom, seconds, strict=True)]
        totals[phase] = sum(seconds)
    per_row.set(xlabel="generation (metrics row)", ylabel="seconds", title="where the time went")
    if timed:
        per_row.legend(fontsize=6, ncol=2)
    whole = sum(totals.values()) or 1.0
    shown = sorted(totals, key=totals.get)
    shares.barh(shown, [totals[p] / whole for p in shown], color=[colors[p] for p in shown])
    for k, phase in enumerate(shown):
        shares.text(totals[phase] / whole, k, f" {totals[phase]:.0f} s", va="center", fontsize=7)
    shares.set(xlabel=f"share of the run's {whole:.0f} s", xlim=(0, 1))


_PHASE_COLORS = (
    "#7f7f7f", "#c7c7c7", "#bcbd22", "#dbdb8d", "#8c564b", "#c49c94", "#1f77b4",
    "#aec7e8", "#9467bd", "#ff7f0e", "#ffbb78", "#2ca02c", "#d62728", "#f7b6d2",
)  # fmt: skip
"""one color per phase of `hola_ray.clock.PHASES`, in order"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hola_ray status", description=__doc__)
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--live", action="store_true", help="also ask the running coordinator")
    parser.add_argument("--json", action="store_true", help="print the view as JSON")
    parser.add_argument("--plot", action="store_true", help="write RUN_DIR/progress.png")
    args = parser.parse_args(argv)
    from hola_ray.experiment.config import CONFIG_NAME

    if (args.run_dir / CONFIG_NAME).is_file():  # an experiment's directory
        from hola_ray.experiment.progress import format_standing, standing

        view = standing(args.run_dir)
        print(json.dumps(view, indent=1) if args.json else format_standing(view))
        return 0
    try:
        view = disk_view(args.run_dir)
    except FileNotFoundError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(json.dumps(view, indent=1) if args.json else format_view(view, "on disk"))
    if args.live:
        live = live_view(args.run_dir)
        if live is None:
            print("live: no coordinator of this run on the cluster (the run is not running)")
        else:
            print(json.dumps(live, indent=1) if args.json else format_view(live, "live"))
    if args.plot and view["generation"] is not None:
        print(f"wrote {plot_progress(args.run_dir)}")
    return 0


def script() -> None:
    """`hola-status` (`[project.scripts]`) and `python -m`: `main`, then a quick exit."""
    from hola_ray.process import leave, pause_collector

    pause_collector()
    leave(main())


if __name__ == "__main__":
    script()
