"""Figures with intervals, and paired differences between methods, from evaluation episodes.

Every trial (method × training seed) is evaluated on the same episodes: per evaluation seed
the same episode seeds, the same drawn seats and teammates (common random numbers). The
intervals come from one stratified bootstrap (contract §5; the held-out protocol of jax-aht):
each draw

- resamples the training seeds of every method, with replacement, within that method, and
- resamples the episodes, with replacement, within each partner-combination stratum (the
  teammates drawn beside the learner), one resample shared by every trial of the draw, so
  that every trial and every method still plays the same episodes.

Where the methods' training seeds are paired (`seeds`: seed s of every method trained
beside the same population build from the same start, as an experiment's are), methods with
the same seeds share the draw of seeds: a draw that takes seed 3 twice takes it twice for
each of them, so a difference A − B is resampled as the seeds' paired differences are, and
what a seed does to both methods (its build, its start) cancels as the shared episodes'
noise does. Methods whose seeds differ are resampled apart.

A figure's standard error is the standard deviation of its bootstrap draws, so it holds both
the spread between training seeds and the episode noise; its 95 % interval is the 2.5th to
97.5th percentile. A difference A − B is taken inside each draw, on the shared episodes, so
the episode noise that A and B share cancels. An interval that contains zero is a tie.

With one training seed per method the draws hold episode noise alone. With three, a method's
seeds can be resampled in only 10 distinct ways: the interval says how the seeds that were
trained spread, not how another three seeds would; it cannot show a difference smaller than
the seeds' spread, and a tie with 3 seeds is not evidence of equality.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from hola_ray.evaluation.metrics import ZERO_SHOT

MEANS = tuple(m.name for m in ZERO_SHOT)
"""per-episode values whose figure is their mean (`hola_ray.evaluation.metrics.ZERO_SHOT`):
success, collision (any seat crashed), length (steps, the horizon when truncated), reward
(the mean per-pursuer return: AT-Drone's REW), learner_crash (the learner's own seat
crashed), teammate_crash (the share of teammate seats that crashed)"""
METRICS = (*MEANS, "steps_success")
"""every figure; steps_success is the mean length over successful episodes only (AT-Drone's
AST): a ratio, NaN where no episode succeeded"""
FIELDS = (*MEANS, "stratum")
"""what an evaluation records per episode (`stratum`: the partner combination's id)"""


def figures(episodes: Mapping[str, np.ndarray]) -> dict[str, float]:
    """One trial's point figures from its episodes ([E] per field)."""
    out = {m: float(np.mean(episodes[m])) for m in MEANS}
    success = np.asarray(episodes["success"], dtype=np.float64)
    out["steps_success"] = (
        float((np.asarray(episodes["length"]) * success).sum() / success.sum())
        if success.sum() > 0
        else float("nan")
    )
    return out


def resample_counts(strata: np.ndarray, draws: int, rng: np.random.Generator) -> np.ndarray:
    """[draws, E]: how often each episode is picked in each draw, when the episodes of every
    stratum are resampled with replacement from that stratum (its size kept)."""
    strata = np.asarray(strata)
    counts = np.zeros((draws, strata.size))
    rows = np.arange(draws)[:, None]
    for stratum in np.unique(strata):
        members = np.flatnonzero(strata == stratum)
        picked = members[rng.integers(0, members.size, size=(draws, members.size))]
        np.add.at(counts, (rows, picked), 1.0)
    return counts


def trial_draws(episodes: Mapping[str, np.ndarray], counts: np.ndarray) -> dict[str, np.ndarray]:
    """One trial's figures [draws] in each draw of `counts` ([draws, E])."""
    total = counts.sum(axis=1)
    out = {m: counts @ np.asarray(episodes[m], dtype=np.float64) / total for m in MEANS}
    success = np.asarray(episodes["success"], dtype=np.float64)
    caught = counts @ success
    with np.errstate(invalid="ignore", divide="ignore"):
        out["steps_success"] = np.where(
            caught > 0, counts @ (np.asarray(episodes["length"]) * success) / caught, np.nan
        )
    return out


def _summary(point: float, draws: np.ndarray) -> dict[str, float | list[float]]:
    finite = draws[np.isfinite(draws)]
    if finite.size == 0:
        return {"mean": point, "se": float("nan"), "ci95": [float("nan"), float("nan")]}
    lo, hi = np.percentile(finite, [2.5, 97.5])
    return {
        "mean": point,
        "se": float(finite.std(ddof=1)) if finite.size > 1 else 0.0,
        "ci95": [float(lo), float(hi)],
    }


def compare(
    methods: Mapping[str, Sequence[Mapping[str, np.ndarray]]],
    pairs: Sequence[tuple[str, str]] = (),
    draws: int = 4000,
    seed: int = 0,
    seeds: Mapping[str, Sequence[int]] | None = None,
    scale: tuple[str, Sequence[str]] | None = None,
) -> tuple[dict[str, dict[str, dict]], dict[str, dict[str, dict]]]:
    """Per method (its trials' episodes, one mapping per training seed, all on the same
    episodes) the figures {metric: {mean, se, ci95}}, and per pair (A, B) the difference
    A − B {metric: {mean, se, ci95}}: the mean over a method's seeds, intervals by the
    stratified bootstrap of the module doc. `seeds`: each method's training seeds, in the
    order of its trials; methods with the same ones are resampled as pairs (module doc).
    `scale`: (the floor's name, the ceilings' names) among `methods` (reference seats, one
    trial each): every other method's figures then hold `normalised`, {ceiling: {mean, se,
    ci95}} of (success − floor's) / (ceiling's − floor's), taken inside each draw
    (`hola_ray.evaluation.scale`)."""
    trials = [t for ts in methods.values() for t in ts]
    if not trials:
        raise ValueError("no trials to compare")
    strata = np.asarray(trials[0]["stratum"])
    for t in trials:
        if not np.array_equal(np.asarray(t["stratum"]), strata):
            raise ValueError(
                "the trials were not evaluated on the same episodes (their partner draws "
                "differ): evaluate them with the same settings"
            )
    rng = np.random.default_rng(seed)
    counts = resample_counts(strata, draws, rng)
    points: dict[str, dict[str, float]] = {}
    method_draws: dict[str, dict[str, np.ndarray]] = {}
    shared: dict[tuple[int, ...], np.ndarray] = {}  # paired seeds → their one resample
    for name, ts in methods.items():
        if not ts:
            raise ValueError(f"method {name} has no trials")
        per_trial = [trial_draws(t, counts) for t in ts]
        own = tuple(seeds[name]) if seeds is not None and name in seeds else None
        if own is not None and len(own) != len(ts):
            raise ValueError(f"method {name}: {len(ts)} trials but seeds {list(own)}")
        picks = shared.get(own) if own is not None else None
        if picks is None:
            picks = rng.integers(0, len(ts), size=(draws, len(ts)))  # training seeds, resampled
            if own is not None:
                shared[own] = picks
        point_rows = [figures(t) for t in ts]
        points[name] = {m: float(_nanmean([p[m] for p in point_rows])) for m in METRICS}
        method_draws[name] = {}
        for m in METRICS:
            stacked = np.stack([d[m] for d in per_trial])  # [seeds, draws]
            chosen = stacked[picks, np.arange(draws)[:, None]]  # [draws, seeds]
            method_draws[name][m] = _nanmean(chosen, axis=1)
    out = {
        name: {m: _summary(points[name][m], method_draws[name][m]) for m in METRICS}
        for name in methods
    }
    if scale is not None:
        floor, ceilings = scale
        for name in methods:
            if name == floor or name in ceilings:
                continue
            out[name]["normalised"] = {
                c: _summary(
                    normalised(
                        points[name]["success"], points[floor]["success"], points[c]["success"]
                    ),
                    normalised(
                        method_draws[name]["success"],
                        method_draws[floor]["success"],
                        method_draws[c]["success"],
                    ),
                )
                for c in ceilings
            }
    diffs: dict[str, dict[str, dict]] = {}
    for a, b in pairs:
        diffs[f"{a}-{b}"] = {
            m: _summary(points[a][m] - points[b][m], method_draws[a][m] - method_draws[b][m])
            for m in METRICS
        }
    return out, diffs


def normalised(value, floor, ceiling):
    """(value − floor) / (ceiling − floor): 0 at the floor's level, 1 at the ceiling's; NaN
    where the ceiling is not above the floor (no scale to read it on)."""
    value, floor, ceiling = (np.asarray(x, dtype=np.float64) for x in (value, floor, ceiling))
    room = ceiling - floor
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(room > 0, (value - floor) / np.where(room > 0, room, 1.0), np.nan)
    return float(out) if out.ndim == 0 else out


def verdict(difference: Mapping[str, object], higher_is_better: bool = True) -> str:
    """'ahead', 'behind' or 'tie' for a difference A − B (its 95 % interval against 0)."""
    lo, hi = difference["ci95"]
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo <= 0 <= hi:
        return "tie"
    above = lo > 0
    return "ahead" if above == higher_is_better else "behind"


HIGHER_IS_BETTER = {
    "success": True,
    "collision": False,
    "length": False,
    "steps_success": False,
    "reward": True,
    "learner_crash": False,
    "teammate_crash": False,
}


def _nanmean(values: np.ndarray, axis: int | None = None) -> np.ndarray | float:
    """The mean of the finite values; NaN, without numpy's warning, where there are none
    (steps_success of a draw in which no picked trial succeeded)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(values, axis=axis)
