"""The PPO update's minibatches, cut by index from the train batch's tensors.

RLlib's `MiniBatchCyclicIterator` slices every column of a `SampleBatch` per minibatch,
concatenates the pieces where an epoch wraps, shuffles by permuting every column, and wraps
each minibatch in a new `MultiAgentBatch`; its update loop then logs step counts and
Prometheus counters per minibatch. With the Oracle's small networks that was a third of a
gradient step's time. `Minibatches` draws the same number of minibatches of the same size
per module (RLlib's rule: `minibatch_size` rows of *every* trained module per step, until
the module with the most rows has covered `num_epochs` epochs; the rows wrap into the next
epoch's order), each a plain mapping module id → column → tensor gathered by one index.
One difference: RLlib walks the first epoch in the batch's order and shuffles only when an
epoch wraps; here every epoch, the first too, is a fresh permutation (`np.random`, the
source RLlib's shuffle draws from).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping

import numpy as np
import torch


class Minibatch:
    """One minibatch as the learner's update loop reads it."""

    __slots__ = ("policy_batches", "rows", "_env_steps")

    def __init__(
        self,
        policy_batches: dict[str, dict[str, torch.Tensor]],
        rows: dict[str, int],
        env_steps: int,
    ):
        self.policy_batches = policy_batches
        """module id → column → tensor [minibatch, ...]"""
        self.rows = rows
        """module id → its rows in this minibatch"""
        self._env_steps = env_steps

    def env_steps(self) -> int:
        """The env steps of the train batch it was cut from (what RLlib reports)."""
        return self._env_steps


class Minibatches:
    """Iterates the minibatches of `num_epochs` epochs over a multi-agent train batch."""

    def __init__(
        self,
        columns: Mapping[str, Mapping[str, torch.Tensor]],
        *,
        env_steps: int,
        num_epochs: int,
        minibatch_size: int | None,
        shuffle: bool = True,
        num_total_minibatches: int = 0,
    ):
        self.columns = {mid: dict(cols) for mid, cols in columns.items()}
        """module id → column → tensor [rows, ...] (the train batch)"""
        self.sizes = {mid: _rows(cols) for mid, cols in self.columns.items()}
        empty = [mid for mid, n in self.sizes.items() if n == 0]
        if empty:
            raise ValueError(f"the train batch of module(s) {empty} is empty")
        self.minibatch = minibatch_size or max(self.sizes.values())
        self.shuffle = shuffle
        self.env_steps = env_steps
        self.steps = num_total_minibatches or max(
            math.ceil(n * num_epochs / self.minibatch) for n in self.sizes.values()
        )
        """gradient steps this update takes"""

    def __len__(self) -> int:
        return self.steps

    def __iter__(self) -> Iterator[Minibatch]:
        streams = {mid: _IndexStream(n, self.shuffle) for mid, n in self.sizes.items()}
        packed = {mid: _Packed(cols) for mid, cols in self.columns.items()}
        for _ in range(self.steps):
            batches, rows = {}, {}
            for mid, columns in packed.items():
                index = streams[mid].take(self.minibatch)
                batches[mid] = columns.gather(index)
                rows[mid] = len(index)
            yield Minibatch(batches, rows, self.env_steps)


class _Packed:
    """A module's columns side by side, one tensor per dtype, so that a minibatch is one
    gather per dtype (not one per column); its columns are views into the gathered rows."""

    def __init__(self, columns: Mapping[str, torch.Tensor]):
        self.parts: list[tuple[torch.Tensor, list[tuple[str, int, int, torch.Size]]]] = []
        """(the columns of one dtype as [rows, width], [(column, start, stop, row shape)])"""
        by_dtype: dict[torch.dtype, list[tuple[str, torch.Tensor]]] = {}
        for name, tensor in columns.items():
            by_dtype.setdefault(tensor.dtype, []).append((name, tensor))
        for group in by_dtype.values():
            rows = len(group[0][1])
            flat = [t.reshape(rows, -1) for _, t in group]
            spans, start = [], 0
            for (name, tensor), f in zip(group, flat, strict=True):
                spans.append((name, start, start + f.shape[1], tensor.shape[1:]))
                start += f.shape[1]
            self.parts.append((torch.cat(flat, dim=1) if len(flat) > 1 else flat[0], spans))

    def gather(self, index: torch.Tensor) -> dict[str, torch.Tensor]:
        out = {}
        for flat, spans in self.parts:
            rows = torch.index_select(flat, 0, index)
            for name, start, stop, shape in spans:
                out[name] = rows[:, start:stop].view(len(index), *shape)
        return out


class _IndexStream:
    """Row indices epoch after epoch (each a permutation when shuffling), taken in pieces
    that wrap from one epoch into the next."""

    def __init__(self, rows: int, shuffle: bool):
        self.rows, self.shuffle = rows, shuffle
        self.buffer = np.empty(0, dtype=np.int64)

    def take(self, n: int) -> torch.Tensor:
        while len(self.buffer) < n:
            # RLlib's own shuffle draws from the global generator, which its seed sets
            order = (
                np.random.permutation(self.rows)  # noqa: NPY002
                if self.shuffle
                else np.arange(self.rows)
            )
            self.buffer = np.concatenate([self.buffer, order])
        out, self.buffer = self.buffer[:n], self.buffer[n:]
        return torch.from_numpy(out)


def _rows(cols: Mapping[str, torch.Tensor]) -> int:
    lengths = {len(v) for v in cols.values()}
    if len(lengths) != 1:
        raise ValueError(f"columns of unequal length {sorted(lengths)} in one module's batch")
    return lengths.pop()
