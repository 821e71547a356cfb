"""A run's figures where people watch them: Ray metrics for the dashboard and Prometheus,
TensorBoard events for the run folder. The coordinator publishes each metrics row here as
it writes it, and each generation's monitored figures once they are played.

Every Ray metric is a gauge named `hola_ray_<figure>`, tagged by `run` (the run, or the
experiment) and `trial` (the experiment's trial; empty for a run of its own), and holds the
value metrics.csv has in the column of `SERIES`. Ray serves them as Prometheus text on the
port `--metrics-port` gives (`python -m hola_ray.run`, `python -m hola_ray.experiment`).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

SERIES = {
    "generation": ("generation", "the last completed generation"),
    "env_steps": ("env_steps", "environment steps trained so far"),
    "env_steps_per_s": ("oracle_env_steps_per_s", "the Oracle's env steps per second"),
    "learner_success": ("learner_success", "the learner's success in its own judging"),
    "learner_collision": ("learner_collision", "the learner's collision rate there"),
    "phi_entropy": ("phi_entropy", "the entropy of phi over the members (nats)"),
    "population_size": ("population_size", "members in the population"),
    "acceptances": ("acceptances", "learners accepted into the population so far"),
    "grapher_episodes_per_s": ("grapher_episodes_per_s", "the Grapher's episodes per second"),
}
"""metric `hola_ray_<name>` → (its metrics.csv column, what it is: ASCII, as Ray asks)"""

TAGS = ("run", "trial")


def summary_writer(folder: Path) -> Any:
    """tensorboardX's writer, imported without torch unless this process has it:
    tensorboardX imports torch where it can only to tell a tensor from an array
    (tensorboardX/writer.py), and the coordinator writes floats. Its process so never
    loads torch (`hola_ray.population.files.TorchFile`)."""
    hidden = "torch" not in sys.modules
    if hidden:
        sys.modules["torch"] = None  # type: ignore[assignment]  # `import torch` fails
    try:
        from tensorboardX import SummaryWriter
    finally:
        if hidden:
            del sys.modules["torch"]
    return SummaryWriter(str(folder))


def _number(value: Any) -> float | None:
    numeric = isinstance(value, int | float) and not isinstance(value, bool)
    return float(value) if numeric and math.isfinite(value) else None


class Telemetry:
    """The gauges and the TensorBoard writer of one run (`tags`: run and trial)."""

    def __init__(self, tensorboard: Path, tags: Mapping[str, str]):
        from ray.util.metrics import Gauge

        self.tags = {k: str(tags.get(k, "")) for k in TAGS}
        self.gauges = {
            name: Gauge(f"hola_ray_{name}", about, TAGS) for name, (_, about) in SERIES.items()
        }
        self.tb = summary_writer(tensorboard)

    def _set(self, row: Mapping[str, Any]) -> None:
        for name, (column, _) in SERIES.items():
            value = _number(row.get(column))
            if value is not None:
                self.gauges[name].set(value, tags=self.tags)

    def row(self, row: Mapping[str, Any], iterations: Sequence[Mapping[str, float]]) -> None:
        """A generation's metrics row as written, and its PPO iterations (TensorBoard, on
        the run's env-step axis; pre-training on its own)."""
        g = row["generation"]
        group = "pretrain" if g == 0 else "iteration"
        before = int(row.get("env_steps", 0)) - int(iterations[-1]["env_steps"]) if g else 0
        for it in iterations:
            for key, value in it.items():
                if key != "env_steps" and math.isfinite(value):
                    self.tb.add_scalar(f"{group}/{key}", value, before + int(it["env_steps"]))
        self._set(row)
        for key, value in row.items():
            if key != "generation" and (number := _number(value)) is not None:
                self.tb.add_scalar(key, number, g)
        self.tb.flush()

    def monitors(self, g: int, figures: Mapping[str, Any]) -> None:
        """Generation g's monitored figures (a self-play learner's success among them)."""
        self._set({k: v for k, v in figures.items() if k != "generation"})
        for key, value in figures.items():
            if (number := _number(value)) is not None:
                self.tb.add_scalar(key, number, g)
        self.tb.flush()

    def close(self) -> None:
        self.tb.close()
