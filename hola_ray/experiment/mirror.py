"""Run directories that live on another node: a trial of `hola_ray.experiment` that runs on
a node which cannot see the experiment's directory (a cluster without a shared
filesystem) trains in a local staging folder and mirrors it, after every generation, to the
experiment's directory on the driver's node.

- `Mirror`: an actor on the driver's node that writes what it is sent under its root.
  A generation folder arrives whole and is written under a temporary name and renamed, so
  it is complete or absent there too; other files are replaced atomically, learner.json
  last (it says a generation's files at the top are all written: `RunDir`).
- `DirectorySync`: the trial's side; each call sends the files that changed since the last
  one (and names the ones that went away, e.g. a rewritten `population/`).
- `pack` / `unpack`: a directory as bytes, to start a partial trial again on any node.
"""

from __future__ import annotations

import io
import os
import shutil
import tarfile
from collections.abc import Mapping, Sequence
from pathlib import Path, PurePosixPath

import ray

from hola_ray.population.rundir import GEN_PREFIX

SKIP = {".lock"}
"""never mirrored: the run-directory lock is per machine"""

LAST = "learner.json"


def _files(root: Path) -> dict[str, Path]:
    return {
        p.relative_to(root).as_posix(): p
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name not in SKIP and ".tmp" not in p.relative_to(root).as_posix()
    }


def _safe(rel: str) -> PurePosixPath:
    path = PurePosixPath(rel)
    if path.is_absolute() or ".." in path.parts or not path.parts:
        raise ValueError(f"refusing to write {rel!r} outside the mirrored directory")
    return path


def _generation_of(rel: PurePosixPath) -> str | None:
    """'gen_0003' for a file under generations/gen_0003/, else None."""
    parts = rel.parts
    if len(parts) >= 3 and parts[0] == "generations" and parts[1].startswith(GEN_PREFIX):
        return parts[1]
    return None


def write_tree(root: Path, files: Mapping[str, bytes], removed: Sequence[str] = ()) -> None:
    """Write `files` (relative path → bytes) under `root`: each generation folder under a
    temporary name, then renamed; the other files atomically, learner.json last."""
    root = Path(root)
    generations: dict[str, dict[PurePosixPath, bytes]] = {}
    others: list[tuple[PurePosixPath, bytes]] = []
    for rel, data in files.items():
        path = _safe(rel)
        gen = _generation_of(path)
        if gen is None:
            others.append((path, data))
        else:
            generations.setdefault(gen, {})[path] = data
    for gen, members in sorted(generations.items()):
        final = root / "generations" / gen
        tmp = root / "generations" / f".tmp_{gen}_mirror"
        shutil.rmtree(tmp, ignore_errors=True)
        if final.exists():  # a generation folder is never rewritten; take what was added
            tmp = final
        for path, data in members.items():
            target = tmp / Path(*path.parts[2:])
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        if tmp != final:
            os.rename(tmp, final)
    for path, data in sorted(others, key=lambda item: item[0].name == LAST):
        target = root / Path(*path.parts)
        target.parent.mkdir(parents=True, exist_ok=True)
        part = target.with_name(target.name + ".mirror-part")
        part.write_bytes(data)
        os.replace(part, target)
    for rel in removed:
        (root / Path(*_safe(rel).parts)).unlink(missing_ok=True)


@ray.remote(num_cpus=0, max_restarts=0)
class Mirror:
    """Writes a trial's run directory on the driver's node (`write_tree`)."""

    def __init__(self, root: str):
        self.root = Path(root)
        self.root.mkdir(parents=True, exist_ok=True)

    def write(self, files: Mapping[str, bytes], removed: Sequence[str] = ()) -> int:
        write_tree(self.root, files, removed)
        return len(files)


class DirectorySync:
    """Sends what changed in `source` since the last call to a `Mirror`."""

    def __init__(self, source: Path, mirror):
        self.source = Path(source)
        self.mirror = mirror
        self.seen: dict[str, tuple[int, int]] = {}

    def _stamps(self, files: dict[str, Path]) -> dict[str, tuple[int, int]]:
        stats = {rel: path.stat() for rel, path in files.items()}
        return {rel: (st.st_size, st.st_mtime_ns) for rel, st in stats.items()}

    def mark_seen(self) -> None:
        """Take what `source` holds now as already mirrored (it came from the mirror)."""
        self.seen = self._stamps(_files(self.source))

    def __call__(self, *_: object) -> int:
        now = _files(self.source)
        stamps = self._stamps(now)
        changed = {
            rel: path.read_bytes() for rel, path in now.items() if self.seen.get(rel) != stamps[rel]
        }
        removed = sorted(set(self.seen) - set(now))
        if changed or removed:
            ray.get(self.mirror.write.remote(changed, removed))
        self.seen = stamps
        return len(changed)


def pack(root: Path) -> bytes:
    """A directory (its files, the lock aside) as gzip'd tar bytes."""
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w:gz") as tar:
        for rel, path in _files(Path(root)).items():
            tar.add(path, arcname=rel)
    return out.getvalue()


def unpack(data: bytes, root: Path) -> None:
    """`pack`'s bytes into `root`, emptied first."""
    root = Path(root)
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as tar:
        if hasattr(tarfile, "data_filter"):
            tar.extractall(root, filter="data")
        else:  # Python 3.11.0-3.11.3 (Debian 12's 3.11.2) has no filters: the same refusal
            for member in tar.getmembers():
                name = PurePosixPath(member.name)
                if (
                    not (member.isfile() or member.isdir())
                    or name.is_absolute()
                    or ".." in name.parts
                ):
                    raise tarfile.TarError(f"unpack: refusing {member.name!r} (not a plain file)")
            tar.extractall(root)
