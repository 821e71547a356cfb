"""How a run directory's files are written and read: whole or not at all (written under a
temporary name, then renamed), and torch files unpickled safely (`load_state`). A torch
file may travel as its bytes (`TorchFile`): the coordinator writes and reads members'
and learners' files without importing torch."""

from __future__ import annotations

import csv
import io
import os
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np


def write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    if not rows:
        return
    columns: list[str] = ["generation"]
    for row in rows:
        columns += [k for k in row if k not in columns]
    tmp = path.with_suffix(".csv.tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


def atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


class UnsafeFile(ValueError):
    """A run-directory file that holds more than tensors, arrays and plain data."""


_ARRAY_GLOBALS = [
    getattr(np, "_core", getattr(np, "core", None)).multiarray._reconstruct,
    np.ndarray,
    np.dtype,
    *(type(np.dtype(t)) for t in ("float32", "float64", "int32", "int64", "bool")),
]
"""what pickling a numpy array names: its reconstructor, its type and its dtype"""


def load_state(path: Path | BinaryIO, name: str | None = None) -> dict[str, Any]:
    """A torch file (an RLlib module state, name → numpy array, or a plain-torch export)
    read with `weights_only=True`: tensors, plain data and numpy arrays (allowed by name),
    nothing else unpickled, so a run directory copied from elsewhere cannot run code on
    `--resume`. A file that would (any other global) is refused in one line naming it
    (`name`, else the path)."""
    import torch

    try:
        with torch.serialization.safe_globals(_ARRAY_GLOBALS):
            return torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as err:
        lines = [x.strip() for x in str(err).splitlines() if x.strip()]
        said = next((x for x in lines if "GLOBAL" in x or "Unsupported" in x), lines[-1])
        raise UnsafeFile(
            f"{name or path}: refused, it holds more than tensors, arrays and plain data ({said})"
        ) from None


class TorchFile:
    """A torch file as bytes: made (`of`) and opened (`load`) where torch is loaded, written
    and read as it is by the coordinator, which so never imports torch (about 2 s of CPU at
    every run's start, most of an idle coordinator's)."""

    __slots__ = ("data",)

    def __init__(self, data: bytes):
        self.data = data

    @classmethod
    def of(cls, obj: Mapping[str, Any]) -> TorchFile:
        """What `torch.save(dict(obj), path)` would write."""
        import torch

        buffer = io.BytesIO()
        torch.save(dict(obj), buffer)
        return cls(buffer.getvalue())

    @classmethod
    def read(cls, path: Path) -> TorchFile:
        return cls(path.read_bytes())

    def load(self) -> dict[str, Any]:
        """Its contents, as `load_state` reads a file."""
        return load_state(io.BytesIO(self.data), name="a torch file from the coordinator")


Saved = Mapping[str, Any] | TorchFile
"""what a run directory holds as a torch file: a mapping (saved here with torch) or its bytes"""


def torch_save(obj: Saved, path: Path) -> None:
    if isinstance(obj, TorchFile):
        path.write_bytes(obj.data)
    else:
        import torch

        torch.save(dict(obj), path)


def atomic_torch_save(obj: Saved, path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    torch_save(obj, tmp)
    os.replace(tmp, path)


def fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
