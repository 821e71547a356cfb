"""The zero-shot evaluation's figures (paper §V, Fig. 4; docs/contract.md §5): a learner against an
unseen teammate pool, and the BR-Prox score. The command: `python -m hola_ray evaluate`.

Per learner and pool, `episodes` episodes per seed: the learner sits in a random seat
and its n_p − 1 teammates are drawn from the pool, uniformly with replacement, per episode.
The figures are means over every episode: success, collision (any seat crashed), length,
AT-Drone's `steps_success` (mean length over successful episodes: AST) and `reward` (mean
per-pursuer return: REW), and whose crashes (`learner_crash`: the learner's own seat;
`teammate_crash`: the share of teammate seats). Standard errors and 95 % intervals come
from a bootstrap over episodes resampled within each partner combination
(`hola_ray.evaluation.compare`). Every learner plays the same episodes (the draws depend on
the seed only), so two learners' figures are paired.

The normalised score follows ZSC-Eval's BR-Prox: for every combination of pool members in
the other seats and every seat, R(ref) is the best mean team return that any pool member
reaches in that seat with those teammates, and the learner's cell scores
min(1, max(R(learner), 0) / R(ref)); cells where no pool member reaches a positive return
(R(ref) ≤ 0) have no reference and are left out (their count is reported). `score_iqm` is
the interquartile mean over combinations × seats × seeds. Each cell plays the same
`cell_episodes` episode seeds for the learner and every pool member.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.compare import FIELDS, METRICS, compare
from hola_ray.evaluation.pools import pool_dir
from hola_ray.evaluation.rollout import rollout
from hola_ray.evaluation.scale import CEILINGS, FLOOR, play_references, reference_figures
from hola_ray.evaluation.stats import episode_seeds
from hola_ray.evaluation.teams import play
from hola_ray.homes import manifest_sha256


# ---- BR-Prox score --------------------------------------------------------------------------
def cell_returns(
    candidates: list, members: list, config: PursuitConfig, episodes: int, seeds: Sequence[int]
) -> np.ndarray:
    """Mean team return [C, n_p, S, K] of each candidate k sitting in seat j with member
    combination c (ordered over the other seats) in the rest. Every (c, j, k) block plays
    the same `episodes` episode seeds: common random numbers for the ratio R / R(ref)."""
    n_p, k_count, m_count = config.n_pursuers, len(candidates), len(members)
    combos = list(itertools.product(range(m_count), repeat=n_p - 1))
    teams = [
        [k_count + m for m in combo[:seat]] + [k] + [k_count + m for m in combo[seat:]]
        for combo in combos
        for seat in range(n_p)
        for k in range(k_count)
    ]
    assignment = np.repeat(np.asarray(teams), episodes, axis=0)
    out = np.zeros((len(combos), n_p, len(seeds), k_count))
    for si, s in enumerate(seeds):
        block = episode_seeds(int(s), episodes)
        result = rollout(
            config,
            [*candidates, *members],
            len(assignment),
            assignment=assignment,
            episode_seeds=np.tile(block, len(teams)),
        )
        returns = result.team_return.reshape(len(combos), n_p, k_count, episodes)
        out[:, :, si, :] = returns.mean(axis=-1)
    return out


def br_prox(reference: np.ndarray, learner: np.ndarray) -> tuple[np.ndarray, int]:
    """Cell scores min(1, max(R, 0) / R_ref) over the cells with R_ref > 0 (flattened), and
    the number of cells left out for want of a reference. reference: [..., M]; learner: [...]."""
    best = reference.max(axis=-1)
    valid = best > 0
    scores = np.minimum(1.0, np.maximum(learner[valid], 0.0) / best[valid])
    return scores, int((~valid).sum())


def iqm(values: np.ndarray) -> float:
    """The interquartile mean: the mean of the middle half (scipy's trim_mean at 25 %)."""
    values = np.sort(np.asarray(values, dtype=np.float64).ravel())
    if values.size == 0:
        return float("nan")
    cut = int(values.size * 0.25)
    middle = values[cut : values.size - cut] if values.size - 2 * cut > 0 else values
    return float(middle.mean())


# ---- the figures ----------------------------------------------------------------------------
def evaluate_learner(
    learner: Any,
    members: list,
    reference: np.ndarray,
    config: PursuitConfig,
    episodes: int,
    seeds: Sequence[int],
    cell_episodes: int,
    seats: Mapping[str, Mapping[str, np.ndarray]] | None = None,
) -> dict[str, Any]:
    """One learner's figures against one pool (`members`), whose reference returns
    (`cell_returns(members, members, …)`) are given: computed once for every learner.
    `seats`: the reference seats' episodes (`hola_ray.evaluation.scale.play_references`,
    the floor and the ceilings on these episodes), for the learner's scale."""
    played = play(learner, members, config, episodes, seeds)
    mine = cell_returns([learner], members, config, cell_episodes, seeds)[..., 0]
    scores, dropped = br_prox(reference, mine)
    seats = dict(seats or {})
    ceilings = [c for c in CEILINGS if c in seats]
    scale = (FLOOR, ceilings) if FLOOR in seats and ceilings else None
    summary = compare({"learner": [played], **{k: [v] for k, v in seats.items()}}, scale=scale)[0]
    intervals = summary["learner"]
    row: dict[str, Any] = {}
    for m in METRICS:
        row[m] = intervals[m]["mean"]
        row[f"{m}_se"] = intervals[m]["se"]
        row[f"{m}_ci95"] = intervals[m]["ci95"]
        if m != "steps_success":
            row[f"{m}_per_seed"] = [
                round(float(played[m][played["eval_seed"] == s].mean()), 4) for s in seeds
            ]
    if scale is not None:
        row["scale"] = {
            "floor": reference_figures(seats[FLOOR]),
            "ceilings": {c: reference_figures(seats[c]) for c in ceilings},
            "normalised": intervals["normalised"],
            "per_episode": {k: episode_record(v) for k, v in seats.items()},
        }
    row["score_iqm"] = iqm(scores)
    row["score_cells"] = int(scores.size)
    row["score_cells_without_reference"] = dropped
    row["episodes"] = episodes * len(seeds)
    row["per_episode"] = episode_record(played)
    return row


def episode_record(played: Mapping[str, np.ndarray]) -> dict[str, list]:
    """Every episode's figures as JSON lists (`hola_ray.evaluation.teams.play`'s fields)."""
    return {
        m: [round(float(x), 4) for x in played[m]]
        if m in ("reward", "teammate_crash")
        else [int(x) for x in played[m]]
        for m in (*FIELDS, "eval_seed")
    }


def pool_fingerprints(names: Sequence[str]) -> dict[str, str]:
    """Pool name → the sha256 of its manifest (which holds every member file's sha256): an
    evaluation cached under one fingerprint is stale once the pool is rebuilt."""
    return {name: manifest_sha256(pool_dir(name)) for name in names}


def evaluate(
    learners: Mapping[str, Any],
    pool_members: Mapping[str, Mapping[str, Any]],
    config: PursuitConfig,
    episodes: int,
    seeds: Sequence[int],
    cell_episodes: int,
    say=print,
    references: Mapping[str, Any] | None = None,
) -> dict[str, dict[str, dict[str, Any]]]:
    """Figures per learner and pool (see the module doc); with `references` (the floor and
    ceilings, `hola_ray.evaluation.scale.load_references`) the learner's scale too."""
    out: dict[str, dict[str, dict[str, Any]]] = {name: {} for name in learners}
    for pool, members_map in pool_members.items():
        members = list(members_map.values())
        start = time.perf_counter()
        reference = cell_returns(members, members, config, cell_episodes, seeds)
        seats = play_references(references or {}, members, config, episodes, seeds)
        took = time.perf_counter() - start
        say(
            f"[{pool}] reference returns of {len(members)} members and "
            f"{len(seats)} reference seats: {took:.0f} s"
        )
        if seats:
            say(f"[{pool}] " + scale_line(seats))
        for name, learner in learners.items():
            start = time.perf_counter()
            row = evaluate_learner(
                learner, members, reference, config, episodes, seeds, cell_episodes, seats
            )
            out[name][pool] = row
            say(
                f"[{pool}] {name}: success {row['success']:.1%} ± {row['success_se']:.1%}, "
                f"collision {row['collision']:.1%} ± {row['collision_se']:.1%} (learner's own "
                f"{row['learner_crash']:.1%}, a teammate's {row['teammate_crash']:.1%}), length "
                f"{row['length']:.0f} ± {row['length_se']:.0f} (successful episodes "
                f"{row['steps_success']:.0f}), reward {row['reward']:.1f}, score IQM "
                f"{row['score_iqm']:.3f} ({time.perf_counter() - start:.0f} s)"
            )
            if "scale" in row:
                say(f"[{pool}] {name}: normalised score " + normalised_line(row["scale"]))
    return out


def scale_line(seats: Mapping[str, Mapping[str, np.ndarray]]) -> str:
    """The reference seats' success, collision and own crash, one line."""
    return "; ".join(
        f"{name} ({'holds its heading' if name == FLOOR else 'ceiling'}): success "
        f"{f['success']:.1%}, collision {f['collision']:.1%}, own crash {f['learner_crash']:.1%}"
        for name, f in ((n, reference_figures(e)) for n, e in seats.items())
    )


def normalised_line(scale: Mapping[str, Any]) -> str:
    """(learner − floor) / (ceiling − floor) per ceiling with its interval, one line."""
    floor = scale["floor"]["success"]
    parts = []
    for name, value in scale["normalised"].items():
        lo, hi = value["ci95"]
        ceiling = scale["ceilings"][name]["success"]
        parts.append(
            f"{value['mean']:.2f} [{lo:.2f}, {hi:.2f}] of the way from the floor ({floor:.1%}) "
            f"to the {name} ceiling ({ceiling:.1%})"
        )
    return "; ".join(parts)
