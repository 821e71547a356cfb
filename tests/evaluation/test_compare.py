"""Intervals and paired differences: a stratified bootstrap over training seeds and episodes."""

from __future__ import annotations

import numpy as np
import pytest

from hola_ray.evaluation.compare import compare, figures, resample_counts, verdict


def trial(success, length=None, strata=None, **rest) -> dict[str, np.ndarray]:
    success = np.asarray(success, dtype=np.float64)
    n = success.size
    out = {
        "success": success,
        "collision": 1.0 - success,
        "length": np.full(n, 100.0) if length is None else np.asarray(length, np.float64),
        "reward": 10.0 * success,
        "learner_crash": np.zeros(n),
        "teammate_crash": np.zeros(n),
        "stratum": np.zeros(n, np.int64) if strata is None else np.asarray(strata),
    }
    return out | {k: np.asarray(v, np.float64) for k, v in rest.items()}


def test_point_figures_hand_worked():
    # two successes of lengths 200 and 400, one failure at the horizon (1000)
    f = figures(trial([1, 1, 0], length=[200, 400, 1000]))
    assert f["success"] == pytest.approx(2 / 3)
    assert f["length"] == pytest.approx(1600 / 3)
    assert f["steps_success"] == pytest.approx(300.0)  # (200 + 400) / 2: successes only
    assert f["reward"] == pytest.approx(20 / 3)
    assert np.isnan(figures(trial([0, 0], length=[1000, 1000]))["steps_success"])


def test_each_stratum_is_resampled_within_itself():
    strata = np.array([0, 0, 0, 1, 1, 2, 2, 2, 2, 2])
    counts = resample_counts(strata, draws=500, rng=np.random.default_rng(1))
    for s in (0, 1, 2):
        np.testing.assert_array_equal(counts[:, strata == s].sum(axis=1), (strata == s).sum())
    assert counts.std(axis=0).min() > 0  # every episode is resampled, not copied


def test_a_method_against_itself_differs_by_exactly_zero():
    rng = np.random.default_rng(0)
    seeds = [trial(rng.random(60) < p) for p in (0.5, 0.7, 0.6)]
    _, diffs = compare({"a": seeds, "b": seeds}, pairs=[("a", "b")], draws=400, seed=3)
    # not the same draws of the training seeds: a − b spreads by the seeds' spread only
    assert diffs["a-b"]["success"]["mean"] == 0.0
    figs, diffs = compare({"a": seeds[:1], "b": seeds[:1]}, pairs=[("a", "b")], draws=400)
    assert diffs["a-b"]["success"]["ci95"] == [0.0, 0.0]  # shared episodes: noise cancels
    assert figs["a"]["success"]["ci95"][0] < figs["a"]["success"]["mean"]


def test_paired_differences_cancel_shared_episode_noise():
    """B succeeds wherever A does, plus 10 % of A's failures: on common episodes the
    difference is certain, though each method's own interval is wide."""
    rng = np.random.default_rng(2)
    hard = rng.random(200)  # how hard each episode is: shared by both methods
    a = trial(hard < 0.5)
    b = trial((hard < 0.5) | ((hard >= 0.5) & (hard < 0.55)))
    figs, diffs = compare({"a": [a], "b": [b]}, pairs=[("b", "a")], draws=2000)
    lo, hi = diffs["b-a"]["success"]["ci95"]
    assert lo > 0  # b is ahead, though ...
    assert figs["a"]["success"]["ci95"][1] > figs["b"]["success"]["ci95"][0]  # ... they overlap
    assert verdict(diffs["b-a"]["success"]) == "ahead"
    assert verdict(diffs["b-a"]["collision"], higher_is_better=False) == "ahead"


def test_the_standard_error_holds_the_training_seeds_spread():
    rng = np.random.default_rng(4)
    episodes = rng.random(150)
    alike = [trial(episodes < 0.6) for _ in range(3)]
    spread = [trial(episodes < p) for p in (0.2, 0.6, 0.95)]
    figs, _ = compare({"alike": alike, "spread": spread}, draws=2000)
    assert figs["spread"]["success"]["se"] > 2 * figs["alike"]["success"]["se"]
    assert figs["alike"]["success"]["se"] > 0  # episode noise alone, with identical seeds


def test_paired_seeds_cancel_what_a_seed_does_to_both_methods():
    """Six seeds whose builds differ widely (a seed's rate 0.2–0.9), where A beats B by 8
    points at every seed on the shared episodes: resampled seed by seed the difference is
    plainly above zero; resampled apart, the seeds' spread swamps it. Seeds that differ
    are resampled apart, as without seeds."""
    rng = np.random.default_rng(5)
    hard = rng.random(300)
    rates = (0.2, 0.35, 0.5, 0.65, 0.8, 0.9)
    a = [trial(hard < r + 0.08) for r in rates]
    b = [trial(hard < r) for r in rates]
    pairs = [("a", "b")]
    _, apart = compare({"a": a, "b": b}, pairs, draws=2000, seed=1)
    six = list(range(6))
    _, paired = compare({"a": a, "b": b}, pairs, draws=2000, seed=1, seeds={"a": six, "b": six})
    assert paired["a-b"]["success"]["mean"] == pytest.approx(0.08, abs=0.01)
    assert paired["a-b"]["success"]["ci95"][0] > 0.05
    assert apart["a-b"]["success"]["ci95"][0] < 0 < apart["a-b"]["success"]["ci95"][1]
    assert paired["a-b"]["success"]["se"] < apart["a-b"]["success"]["se"] / 5
    other = {"a": six, "b": [s + 6 for s in six]}
    _, unpaired = compare({"a": a, "b": b}, pairs, draws=2000, seed=1, seeds=other)
    assert unpaired == apart
    with pytest.raises(ValueError, match="6 trials but seeds"):
        compare({"a": a, "b": b}, pairs, seeds={"a": six[:5], "b": six})


def test_trials_on_other_episodes_cannot_be_compared():
    a = trial([1, 0, 1], strata=[0, 1, 1])
    b = trial([1, 0, 1], strata=[1, 1, 0])
    with pytest.raises(ValueError, match="not evaluated on the same episodes"):
        compare({"a": [a], "b": [b]})


def test_a_tie_is_an_interval_that_holds_zero():
    assert verdict({"mean": 0.05, "ci95": [-0.01, 0.1]}) == "tie"
    assert verdict({"mean": -0.05, "ci95": [-0.1, -0.01]}) == "behind"
    assert verdict({"mean": 30.0, "ci95": [10.0, 50.0]}, higher_is_better=False) == "behind"
