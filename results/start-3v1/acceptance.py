"""Why a candidate joins or not, generation by generation (issue 35 item 5): for each trial
of an experiment (or run directories), per generation the decision, the candidate's η and
rank, the φ the learner trained against, and for each member its bar (its best hyperedge
among the members before the candidate came) against the candidate's best hyperedge with
that member: a member prefers the candidate (η > 0) only when the second beats the first.

    python results/start-3v1/acceptance.py runs/start-3v1 > results/start-3v1/acceptance.txt

It reads run directories; it trains and chooses nothing.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def read(path: Path):
    return json.loads(path.read_text())


def by_node(item: tuple[str, float]) -> int:
    return int(item[0])


def trial_dirs(paths: list[str]) -> list[Path]:
    out = []
    for p in map(Path, paths):
        out += sorted(d for d in (p / "trials").iterdir()) if (p / "trials").is_dir() else [p]
    return out


def report(run: Path) -> list[str]:
    gens = sorted((run / "generations").glob("gen_*"))
    lines = [f"{run.name}"]
    accepted = 0
    for before, folder in zip(gens, gens[1:], strict=False):
        state = read(folder / "state.json")
        decision = state["decision"]
        if decision is None:
            continue
        members = [int(v) for v in read(before / "state.json")["population"]["slots"]]
        graph = read(before / "hyfog.json")["edges"]
        bars = {
            v: max((e["weight"] for e in graph if v in e["nodes"]), default=None) for v in members
        }
        edges = read(folder / "edges.json")
        best_with = {
            v: max((e["team_return"] for e in edges if v in e["nodes"]), default=None)
            for v in members
        }
        phi = read(before / "phi.json")
        accepted += bool(decision["accepted"])
        prefers = sum(
            1
            for v in members
            if best_with[v] is not None and bars[v] is not None and best_with[v] > bars[v]
        )
        row = read(folder / "metrics.json")
        lines.append(
            f"  gen {int(folder.name[4:]):>2}: {'accepted' if decision['accepted'] else 'rejected'}"
            f" (rank {decision['rank']}, η {decision['eta']:.2f}, {prefers}/{len(members)} members"
            f" prefer it); its edges' mean return {row.get('learner_return', float('nan')):.1f}"
            f" (success {row.get('learner_success', float('nan')):.0%});"
            f" φ {', '.join(f'{k}:{v:.2f}' for k, v in sorted(phi.items(), key=by_node))}"
        )
        lines.append(
            "          member: bar → candidate's best edge with it: "
            + ", ".join(
                f"{v}: {bars[v]:.1f} → {best_with[v]:.1f}"
                for v in members
                if bars[v] is not None and best_with[v] is not None
            )
        )
    lines.append(f"  accepted {accepted} of {len(gens) - 1}")
    return lines


def main(argv: list[str]) -> int:
    for run in trial_dirs(argv):
        if (run / "generations").is_dir():
            print("\n".join(report(run)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
