"""The learner's scale: a floor seat that holds its heading, ceilings chosen on validation and
committed with a manifest, and the normalised score on the learner's own episodes."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.compare import compare, normalised
from hola_ray.evaluation.pools import PoolError
from hola_ray.evaluation.scale import (
    CEILINGS,
    FLOOR,
    REFERENCE_DIR,
    choose,
    load_references,
    play_references,
    write_reference,
)
from hola_ray.evaluation.trajectory import record
from hola_ray.evaluation.zero_shot import cell_returns, evaluate_learner
from hola_ray.policies.learned import random_export
from hola_ray.policies.registry import make_policy

CONFIG = dataclasses.replace(PursuitConfig(), horizon=150)


def test_the_floor_seat_never_turns():
    """`hold` flies straight from its spawn: its heading never changes while it flies."""
    hold = make_policy("hold", CONFIG)
    assert (hold.act(np.zeros((5, CONFIG.obs_dim), np.float32)) == 0.5).all()
    for seed in range(3):
        trajectory = record(CONFIG, [hold, hold, hold], seed=seed)
        heading = trajectory.pursuer_heading  # [T, n_p]
        active = trajectory.pursuer_active
        moved = np.abs(np.diff(heading, axis=0))[active[1:] & active[:-1]]
        assert moved.size > 0 and moved.max() < 1e-9


def test_normalised_is_zero_at_the_floor_one_at_the_ceiling_and_nan_without_room():
    assert normalised(0.5, 0.5, 0.8) == 0.0
    assert normalised(0.8, 0.5, 0.8) == 1.0
    assert normalised(0.65, 0.5, 0.8) == pytest.approx(0.5)  # (0.65 − 0.5) / 0.3
    assert np.isnan(normalised(0.7, 0.6, 0.6))
    np.testing.assert_allclose(normalised(np.array([0.5, 0.9]), 0.5, 0.9), [0.0, 1.0])


def episodes(success: list[int]) -> dict[str, np.ndarray]:
    n = len(success)
    zeros = np.zeros(n)
    return {
        "success": np.asarray(success),
        "collision": zeros,
        "length": np.full(n, 100),
        "reward": zeros,
        "learner_crash": zeros,
        "teammate_crash": zeros,
        "stratum": np.arange(n) % 2,
    }


def test_the_normalised_score_is_read_on_the_shared_episodes():
    floor = episodes([0, 1] * 50)  # 50 %
    ceiling = episodes([1, 1, 1, 0] * 25)  # 75 %
    learner = episodes([1, 1, 0, 0] * 25)  # 50 %: at the floor
    figures, _ = compare(
        {"learner": [learner], "floor": [floor], "top": [ceiling]}, scale=("floor", ["top"])
    )
    score = figures["learner"]["normalised"]["top"]
    assert score["mean"] == pytest.approx(0.0)
    assert score["ci95"][0] < 0 < score["ci95"][1]
    assert "normalised" not in figures["floor"] and "normalised" not in figures["top"]
    same, _ = compare(
        {"learner": [ceiling], "floor": [floor], "top": [ceiling]}, scale=("floor", ["top"])
    )
    assert same["learner"]["normalised"]["top"]["ci95"] == pytest.approx([1.0, 1.0])


def test_the_ceilings_are_chosen_on_validation_and_committed_with_their_hashes(tmp_path):
    records = {"a": {"score": 0.5}, "b": {"score": 0.7}, "c": {"score": 0.7}}
    assert choose(records) == "b"
    config = PursuitConfig(n_evaders=2)
    learned = tmp_path / "mine.pt"
    torch.save(random_export(config.obs_dim, hidden=(8,)) | {"scenario": config.to_dict()}, learned)
    folder = tmp_path / "reference"
    write_reference(
        config,
        ["greedy", "apf-a-10"],
        [learned],
        episodes=4,
        seeds=[0],
        folder=folder,
        say=lambda _: None,
    )
    manifest = json.loads((folder / "manifest.json").read_text())
    hand = manifest["candidates"]["handwritten"]
    assert manifest["ceilings"]["handwritten"]["policy"] == choose(hand)
    assert set(hand) == {"greedy", "apf-a-10"} and manifest["floor"]["policy"] == "hold"
    for figures in hand.values():
        assert figures["score"] == pytest.approx(
            figures["success"] - figures["learner_crash"], abs=1e-4
        )
    seats = load_references(config, folder)
    assert set(seats) == {FLOOR, *CEILINGS}
    assert set(load_references(PursuitConfig(n_evaders=1), folder)) == {FLOOR, "handwritten"}
    (folder / "learned.pt").write_bytes(b"changed")
    with pytest.raises(PoolError, match="sha256"):
        load_references(config, folder)


def test_the_committed_references_are_no_evaluation_pool_member():
    from hola_ray.evaluation.pools import EVALUATION_POOLS, pooled_files

    manifest = json.loads((REFERENCE_DIR / "manifest.json").read_text())
    held_out = {mid for ids in EVALUATION_POOLS.values() for mid in ids}
    assert manifest["ceilings"]["handwritten"]["policy"] not in held_out
    assert manifest["ceilings"]["learned"]["sha256"] not in pooled_files()
    seats = load_references(PursuitConfig(n_evaders=2))
    assert set(seats) == {FLOOR, *CEILINGS}


def test_an_evaluation_reports_the_scale_on_the_learners_episodes():
    members = [make_policy(n, CONFIG) for n in ("greedy", "vicsek")]
    seats = {
        FLOOR: make_policy("hold", CONFIG),
        "handwritten": make_policy("apf-a-10", CONFIG),
    }
    played = play_references(seats, members, CONFIG, 6, [0])
    reference = cell_returns(members, members, CONFIG, 1, [0])
    learner = make_policy("apf-a-10", CONFIG)  # the ceiling itself
    row = evaluate_learner(learner, members, reference, CONFIG, 6, [0], 1, played)
    scale = row["scale"]
    assert scale["floor"]["success"] == pytest.approx(float(played[FLOOR]["success"].mean()))
    assert scale["per_episode"][FLOOR]["success"] == [int(x) for x in played[FLOOR]["success"]]
    if scale["ceilings"]["handwritten"]["success"] > scale["floor"]["success"]:
        assert scale["normalised"]["handwritten"]["mean"] == pytest.approx(1.0)
    assert "scale" not in evaluate_learner(learner, members, reference, CONFIG, 6, [0], 1)
