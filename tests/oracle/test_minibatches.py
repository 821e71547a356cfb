"""The update's minibatches: as many, as large and per module as RLlib's cyclic iterator
cuts them, every row seen once per epoch, the columns of a row kept together."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch
from ray.rllib.utils.minibatch_utils import MiniBatchCyclicIterator

from hola_ray.oracle.minibatches import Minibatches


def columns(sizes: dict[str, int]) -> dict[str, dict[str, torch.Tensor]]:
    """Per module: a row id column and a second column derived from it."""
    return {
        mid: {
            "row": torch.arange(n),
            "obs": torch.arange(n, dtype=torch.float32)[:, None] * torch.ones(1, 3),
        }
        for mid, n in sizes.items()
    }


@pytest.mark.parametrize(
    "sizes, minibatch, epochs",
    [
        ({"learner": 1000}, 256, 4),
        ({"learner": 1024}, 256, 3),
        ({"learner": 700}, 1024, 10),
        ({"m0": 900, "m1": 1300, "m2": 400}, 256, 5),
    ],
)
def test_as_many_minibatches_of_the_same_size_per_module_as_rllibs(sizes, minibatch, epochs):
    cols = columns(sizes)
    ours = list(Minibatches(cols, env_steps=500, num_epochs=epochs, minibatch_size=minibatch))
    batch = MultiAgentBatch(
        {mid: SampleBatch({k: v.numpy() for k, v in c.items()}) for mid, c in cols.items()},
        env_steps=500,
    )
    theirs = list(
        MiniBatchCyclicIterator(
            batch, num_epochs=epochs, minibatch_size=minibatch, shuffle_batch_per_epoch=True
        )
    )
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs, strict=True):
        assert set(a.policy_batches) == set(b.policy_batches)
        for mid in a.policy_batches:
            assert a.rows[mid] == len(b.policy_batches[mid]) == minibatch
        assert a.env_steps() == b.env_steps() == 500


def test_every_row_once_per_epoch_and_its_columns_together():
    n, minibatch, epochs = 1000, 250, 3  # whole epochs: 4 minibatches each
    np.random.seed(0)  # noqa: NPY002 - the iterator draws from the global generator
    out = list(
        Minibatches(columns({"l": n}), env_steps=n, num_epochs=epochs, minibatch_size=minibatch)
    )
    assert len(out) == 12
    rows = [m.policy_batches["l"]["row"] for m in out]
    for e in range(epochs):
        seen = torch.cat(rows[4 * e : 4 * e + 4])
        assert sorted(seen.tolist()) == list(range(n))
    first = torch.cat(rows[:4])
    assert not torch.equal(first, torch.arange(n))  # shuffled, the first epoch too
    for m in out:
        batch = m.policy_batches["l"]
        assert torch.equal(batch["obs"][:, 0], batch["row"].float())


def test_rows_wrap_into_the_next_epoch_and_no_row_repeats_within_one():
    n, minibatch, epochs = 300, 128, 2  # ceil(600 / 128) = 5 minibatches, 640 rows
    np.random.seed(1)  # noqa: NPY002
    out = list(
        Minibatches(columns({"l": n}), env_steps=n, num_epochs=epochs, minibatch_size=minibatch)
    )
    rows = torch.cat([m.policy_batches["l"]["row"] for m in out]).tolist()
    assert len(out) == 5 and len(rows) == 640
    assert sorted(rows[:300]) == list(range(n)) and sorted(rows[300:600]) == list(range(n))
    assert len(set(rows[600:])) == 40


def test_without_a_minibatch_size_each_step_takes_the_whole_batch():
    out = list(Minibatches(columns({"l": 77}), env_steps=77, num_epochs=3, minibatch_size=None))
    assert [m.rows["l"] for m in out] == [77, 77, 77]


def test_an_empty_module_batch_is_refused():
    with pytest.raises(ValueError, match="empty"):
        Minibatches(columns({"l": 0}), env_steps=0, num_epochs=1, minibatch_size=8)
