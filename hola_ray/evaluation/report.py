"""The zero-shot evaluation's figures as a picture and a table: Fig. 4's layout (success,
collision, length) and AT-Drone's steps to success and reward, one bar per learner or
method with its 95 % interval, and the same figures as markdown."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

PANELS = {
    "success": "success rate",
    "collision": "collision rate",
    "length": "episode length",
    "steps_success": "steps to success (AST)",
    "reward": "per-pursuer return (REW)",
}
"""Fig. 4's three columns, then AT-Drone's two"""


POOL_LABELS = {"hot": "HoT", "het": "HeT"}
"""the pools as the paper names them"""


def table_lines(results: Mapping[str, Mapping[str, Mapping[str, Any]]], first: str) -> list[str]:
    """A markdown table of every learner's (method's) figures with their 95 % intervals."""

    def cell(r: Mapping[str, Any], m: str) -> str:
        value, (lo, hi) = r[m], r.get(f"{m}_ci95", (float("nan"),) * 2)
        if m in ("length", "steps_success", "reward"):
            return f"{value:.1f} [{lo:.1f}, {hi:.1f}]"
        return f"{value:.1%} [{lo:.1%}, {hi:.1%}]"

    pool_names = sorted({p for r in results.values() for p in r}, key=lambda p: (p != "hot", p))
    ceilings = sorted(
        {
            c
            for r in results.values()
            for x in r.values()
            for c in x.get("scale", {}).get("normalised", {})
        }
    )
    lines = [
        f"| {first} | pool | success | collision | length | steps to success | reward "
        "| learner crashed | score (IQM) |" + "".join(f" normalised ({c}) |" for c in ceilings),
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |" + " --- |" * len(ceilings),
    ]
    for n, by_pool in results.items():
        for pool in pool_names:
            r = by_pool.get(pool)
            if r:
                cells = " | ".join(cell(r, m) for m in (*PANELS, "learner_crash") if m in r)
                score = r.get("score_iqm", r.get("score", float("nan")))
                scaled = r.get("scale", {}).get("normalised", {})
                extra = "".join(
                    f" {scaled[c]['mean']:.2f} [{scaled[c]['ci95'][0]:.2f}, "
                    f"{scaled[c]['ci95'][1]:.2f}] |"
                    if c in scaled
                    else " |"
                    for c in ceilings
                )
                lines.append(f"| {n} | {pool} | {cells} | {score:.3f} |{extra}")
    scales = {
        pool: r[pool]["scale"]
        for pool in pool_names
        for r in results.values()
        if "scale" in r.get(pool, {})
    }
    if scales:
        lines += [
            "",
            "The learner's scale: the same episodes with a seat that holds its heading (the "
            "floor) and with each ceiling in the learner's place; normalised = (success − "
            "floor's) / (ceiling's − floor's), [95 % interval].",
            "",
            "| pool | seat | success | collision | own crash |",
            "| --- | --- | --- | --- | --- |",
        ]
        for pool, scale in scales.items():
            seats = {"floor (holds its heading)": scale["floor"]} | {
                f"ceiling: {c}": f for c, f in scale["ceilings"].items()
            }
            for seat, f in seats.items():
                lines.append(
                    f"| {pool} | {seat} | {f['success']:.1%} | {f['collision']:.1%} | "
                    f"{f['learner_crash']:.1%} |"
                )
    return lines


def plot(results: Mapping[str, Mapping[str, Mapping[str, Any]]], out: Path) -> tuple[Path, Path]:
    """Fig. 4's layout (a row per pool; success, collision, length) and AT-Drone's steps to
    success and reward, one bar per learner with its 95 % interval; and the same figures
    as a markdown table (`evaluation.md`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    pool_names = sorted({p for r in results.values() for p in r}, key=lambda p: (p != "hot", p))
    fig, axes = plt.subplots(
        len(pool_names), len(PANELS), figsize=(17, 3.2 * len(pool_names)), squeeze=False
    )
    labels = POOL_LABELS
    colors = plt.cm.tab10(np.arange(len(names)) % 10)
    for i, pool in enumerate(pool_names):
        for j, (m, title) in enumerate(PANELS.items()):
            ax = axes[i, j]
            rows = [results[n].get(pool, {}) for n in names]
            values = np.array([r.get(m, np.nan) for r in rows], dtype=np.float64)
            bounds = np.array(
                [r.get(f"{m}_ci95", (np.nan, np.nan)) for r in rows], dtype=np.float64
            ).reshape(len(names), 2)
            errors = np.nan_to_num(np.abs(bounds - values[:, None]).T)
            ax.bar(range(len(names)), values, yerr=errors, color=colors, capsize=4)
            scale = next((r["scale"] for r in rows if "scale" in r), None)
            if scale is not None and m in ("success", "collision"):  # the learner's scale
                ax.axhline(scale["floor"][m], color="0.4", ls="--", lw=1, label="floor (hold)")
                for c, style in zip(scale["ceilings"], (":", "-."), strict=False):
                    ax.axhline(
                        scale["ceilings"][c][m], color="0.2", ls=style, lw=1, label=f"ceiling: {c}"
                    )
                if i == 0 and m == "success":
                    ax.legend(fontsize=7, loc="lower right")
            ax.set_xticks(range(len(names)), names, rotation=20, ha="right", fontsize=8)
            ax.set_title(f"{labels.get(pool, pool)}: {title}", fontsize=9)
            if m in ("success", "collision"):
                ax.set_ylim(0, 1)
    fig.suptitle("bars: mean; whiskers: 95 % interval (stratified bootstrap)", fontsize=9)
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    png = out / "evaluation.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    md = out / "evaluation.md"
    md.write_text("\n".join(table_lines(results, "learner")) + "\n")
    return png, md
