"""A learned pursuer for a flight stack: its deterministic actor as an ONNX graph, and a
manifest that says what the graph reads and what its output means.

The graph takes the raw observation of contract §1 ([N, obs_dim] float32, the layout of
`ObsLayout`), appends the proximity features itself when the actor was trained with them,
and returns the action the arena takes (`action`, [N] in [0, 1]) and the heading change it
commands (`heading_change`, [N] radians, positive to the left). It is the arithmetic of
`MLPPolicy.act`, run by any ONNX runtime. `onnx` and `onnxruntime` come with the
`deploy` extra (`pip install -e '.[deploy]'`).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from hola_ray.config.layout import ObsLayout
from hola_ray.config.scenario import PursuitConfig
from hola_ray.policies.base import Policy
from hola_ray.policies.learned import BETA_MAX_CONCENTRATION, MLPPolicy

MANIFEST_FORMAT = "hola_ray.onnx/1"
"""The version tag of the manifest."""

OPSET = 17
"""The ONNX operator set the graph is written in (onnxruntime ≥ 1.12 reads it)."""

INPUT, OUTPUTS = "observation", ("action", "heading_change")


class DeterministicActor(torch.nn.Module):
    """`MLPPolicy.act` as a torch module: raw observations [N, D] → (action [N] in
    [low, high], heading change [N] in radians)."""

    def __init__(self, policy: MLPPolicy) -> None:
        super().__init__()
        self.layers = torch.nn.ModuleList()
        for w, b in zip(policy.weights, policy.biases, strict=True):
            layer = torch.nn.Linear(w.shape[1], w.shape[0])
            layer.weight.data.copy_(w)
            layer.bias.data.copy_(b)
            self.layers.append(layer)
        self.activation = policy.activation
        self.dist = policy.dist
        self.features = bool(policy.feature_indices)
        self.register_buffer("indices", torch.tensor(policy.feature_indices, dtype=torch.long))
        self.gain = policy.feature_gain
        self.low, self.high = policy.low, policy.high
        self.max_turn = policy.config.max_turn

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = obs
        if self.features:
            x = torch.cat([x, torch.exp(-self.gain * x.index_select(1, self.indices))], dim=1)
        last = len(self.layers) - 1
        for k, layer in enumerate(self.layers):
            x = layer(x)
            if k < last:
                x = self.activation(x)
        if self.dist == "gaussian":
            mean = x[:, 0]
        else:
            c = (torch.nn.functional.softplus(x) + 1.0).clamp(max=BETA_MAX_CONCENTRATION)
            c1, c0 = c[:, 0], c[:, 1]
            mean = 2.0 * (c1 / (c1 + c0)) - 1.0
        action = self.low + (mean + 1.0) * ((self.high - self.low) / 2.0)
        action = action.clamp(self.low, self.high)
        return action, (2.0 * action - 1.0) * self.max_turn


def export_onnx(policy: MLPPolicy, path: str | Path) -> Path:
    """Write `policy`'s deterministic actor as an ONNX graph with a dynamic batch axis."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    actor = DeterministicActor(policy).eval()
    example = torch.zeros((2, policy.layout.dim), dtype=torch.float32)
    torch.onnx.export(
        actor,
        (example,),
        str(path),
        input_names=[INPUT],
        output_names=list(OUTPUTS),
        dynamic_axes={INPUT: {0: "batch"}, **{name: {0: "batch"} for name in OUTPUTS}},
        opset_version=OPSET,
        dynamo=False,
    )
    return path


def observation_entries(config: PursuitConfig) -> list[dict[str, Any]]:
    """One entry per observation index: what it measures, frame, units, scale and the
    value it reads when unobserved, as a flight stack must fill it (contract §1). Each block
    starts where the config's `ObsLayout` puts it, so the manifest cannot drift from the
    layout the simulator writes."""
    layout = config.layout
    blocks = (
        (layout.evaders, _evader_entries(config, layout)),
        (layout.obstacle, _obstacle_entries(config)),
        (layout.teammates, _teammate_entries(config, layout)),
        (layout.own, _own_entries(config)),
        (layout.base_dim, _heading_entries(config, layout)),
    )
    out: list[dict[str, Any]] = []
    for offset, entries in blocks:
        assert len(out) == offset
        out.extend({"index": offset + k} | e for k, e in enumerate(entries))
    assert len(out) == layout.dim
    return out


_EGO = "this drone's body frame: the angle from its heading, positive to its left (CCW)"
"""The frame of every bearing and relative heading."""

_ANGLE = "divided by π, in [−1, 1]"
"""The scale of every angle."""

_SEEN = "always observed"
"""What an entry that no state can hide reads when unobserved."""


def _entry(
    name: str, measures: str, frame: str, units: str, scaled: str, unobserved: Any
) -> dict[str, Any]:
    """One observation entry, its index left to `observation_entries`."""
    return {
        "name": name,
        "measures": measures,
        "frame": frame,
        "units": units,
        "scale": scaled,
        "unobserved": unobserved,
    }


def _evader_entries(config: PursuitConfig, layout: ObsLayout) -> list[dict[str, Any]]:
    """(distance, bearing, relative heading) of each evader, in evader order."""
    scale, far = config.obs_distance_scale, config.unobserved_distance
    out = []
    for e in range(layout.n_evaders):
        captured = f"reads {far} (and 0, 0 for the next two) once evader {e} is captured"
        out += [
            _entry(
                f"evader_{e}.distance",
                f"distance from this drone to evader {e}",
                "world (a length)",
                "m",
                f"divided by {scale}",
                captured,
            ),
            _entry(f"evader_{e}.bearing", f"direction to evader {e}", _EGO, "rad", _ANGLE, 0.0),
            _entry(
                f"evader_{e}.heading",
                f"evader {e}'s heading (direction of motion) minus this drone's heading",
                _EGO,
                "rad",
                _ANGLE,
                0.0,
            ),
        ]
    return out


def _obstacle_entries(config: PursuitConfig) -> list[dict[str, Any]]:
    """(distance, bearing) of the nearest obstacle point, which is always there."""
    return [
        _entry(
            "obstacle.distance",
            "distance to the nearest point of a wall, a bar, or a disabled (landed) teammate",
            "world (a length)",
            "m",
            f"divided by {config.obs_distance_scale}",
            _SEEN,
        ),
        _entry("obstacle.bearing", "direction to that nearest point", _EGO, "rad", _ANGLE, _SEEN),
    ]


def _teammate_entries(config: PursuitConfig, layout: ObsLayout) -> list[dict[str, Any]]:
    """(distance, bearing) of each other pursuer, in seat order with this drone left out."""
    gone = (
        f"reads {config.unobserved_distance} (and bearing 0) beyond {config.perception_range} "
        "m or once that teammate is disabled"
    )
    out = []
    for j in range(layout.n_pursuers - 1):
        out += [
            _entry(
                f"teammate_{j}.distance",
                f"distance to the {j}-th other pursuer, in seat order with this drone left out",
                "world (a length)",
                "m",
                f"divided by {config.obs_distance_scale}",
                gone,
            ),
            _entry(f"teammate_{j}.bearing", "direction to that teammate", _EGO, "rad", _ANGLE, 0.0),
        ]
    return out


def _own_entries(config: PursuitConfig) -> list[dict[str, Any]]:
    """This drone's position and heading in the arena frame, the only absolute readings."""
    arena = (
        "arena frame: origin at the lower-left corner, x right, y up "
        f"({config.arena_width} × {config.arena_height} m)"
    )
    return [
        _entry("own.x", "this drone's x", arena, "m", f"divided by {config.arena_width}", _SEEN),
        _entry("own.y", "this drone's y", arena, "m", f"divided by {config.arena_height}", _SEEN),
        _entry("own.cos_heading", "cos of this drone's heading", arena, "1", "none", _SEEN),
        _entry("own.sin_heading", "sin of this drone's heading", arena, "1", "none", _SEEN),
    ]


def _heading_entries(config: PursuitConfig, layout: ObsLayout) -> list[dict[str, Any]]:
    """The other pursuers' relative headings, which follow the base observation only with
    `observe_headings` (none otherwise)."""
    return [
        _entry(
            f"teammate_{j}.heading",
            f"the {j}-th other pursuer's heading minus this drone's heading",
            _EGO,
            "rad",
            _ANGLE,
            f"reads 0 beyond {config.perception_range} m or once disabled",
        )
        for j in range(layout.dim - layout.base_dim)
    ]


def manifest(
    policy: MLPPolicy,
    onnx_path: Path,
    source: Mapping[str, Any],
) -> dict[str, Any]:
    """What a flight stack needs to fly `onnx_path` without reading this code."""
    config = policy.config
    return {
        "format": MANIFEST_FORMAT,
        "onnx": {
            "file": onnx_path.name,
            "sha256": hashlib.sha256(onnx_path.read_bytes()).hexdigest(),
            "opset": OPSET,
            "input": {"name": INPUT, "shape": ["batch", policy.layout.dim], "dtype": "float32"},
            "outputs": [
                {"name": OUTPUTS[0], "shape": ["batch"], "dtype": "float32"},
                {"name": OUTPUTS[1], "shape": ["batch"], "dtype": "float32"},
            ],
        },
        "observation": observation_entries(config),
        "action": {
            "name": OUTPUTS[0],
            "range": [policy.low, policy.high],
            "meaning": (
                "turn the heading by (2·action − 1)·max_turn (the graph's heading_change, "
                "radians, positive to the left), then fly the control period along the new "
                "heading at the pursuer speed"
            ),
            "max_turn_rad": config.max_turn,
            "max_turn_deg": math.degrees(config.max_turn),
            "speed_m_s": config.pursuer_speed,
            "velocity_setpoint": "speed·(cos θ, sin θ) in the arena frame, θ the new heading",
        },
        "control_period_s": config.dt,
        "heading": (
            "the heading θ the observation's bearings and own.cos/sin_heading use is the one "
            "the ground station integrates from the policy's heading changes, starting at "
            "+y (π/2)"
        ),
        "unit_conventions": "metres, seconds, radians; arena frame origin at its lower-left corner",
        "team": team_entry(config),
        "scenario": config.to_dict(),
        "source": dict(source),
    }


def team_entry(config: PursuitConfig) -> dict[str, Any]:
    """The teams and arena a policy of this scenario plays (contract §6): its observation's
    slots hold any team up to them, the missing teammates read as unobserved and the
    missing evaders as captured; the sizes and arena it was trained with."""
    trained = config.team.sizes(config.n_pursuers)
    return {
        "pursuers": [1, config.pursuer_slots],
        "evaders": [1, config.evader_slots],
        "trained_pursuers": [trained[0], trained[-1]],
        "trained_evaders": config.n_evaders,
        "team_changes": config.team.changes,
        "arena": config.arena,
        "arenas": list(config.arenas or (config.arena,)),
        "meaning": (
            "teams of `pursuers` (the learner among them) against `evaders` fill the "
            "observation's slots, the missing teammates as unobserved and the missing "
            "evaders as captured; trained with teams in play of `trained_pursuers` against "
            "`trained_evaders` in `arenas` (drawn per episode where several; `arena` the "
            "first), the team changing `team_changes` times an episode"
        ),
    }


def write_manifest(path: Path, data: Mapping[str, Any]) -> Path:
    path.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
    return path


def onnx_actions(onnx_path: str | Path, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(action, heading_change) of observations [N, D] by onnxruntime, on the CPU."""
    return OnnxPolicy.session(onnx_path).run(
        list(OUTPUTS), {INPUT: np.asarray(obs, dtype=np.float32)}
    )


def read_manifest(onnx_path: str | Path) -> dict[str, Any]:
    """The manifest written beside an ONNX file (OUT.json for OUT.onnx), its hash checked."""
    onnx_path = Path(onnx_path)
    path = onnx_path.with_suffix(".json")
    if not path.is_file():
        raise ValueError(f"{onnx_path}: no manifest {path.name} beside it (write both with export)")
    data = json.loads(path.read_text())
    if data.get("format") != MANIFEST_FORMAT:
        raise ValueError(f"{path}: not a {MANIFEST_FORMAT} manifest")
    got = hashlib.sha256(onnx_path.read_bytes()).hexdigest()
    if got != data["onnx"]["sha256"]:
        raise ValueError(
            f"{onnx_path}: sha256 {got[:12]}…, its manifest says {data['onnx']['sha256'][:12]}…"
        )
    return data


class OnnxPolicy(Policy):
    """A pursuer played from its ONNX file by onnxruntime, as a flight stack would."""

    def __init__(self, onnx_path: str | Path, config: PursuitConfig | None = None) -> None:
        data = read_manifest(onnx_path)
        trained = PursuitConfig.from_dict(data["scenario"])
        super().__init__(config or trained)
        if self.config.layout != trained.layout:  # any team its observation's slots hold
            raise ValueError(
                f"{onnx_path} reads {trained.pursuer_slots} pursuers and "
                f"{trained.evader_slots} evaders (up to {trained.pursuer_slots} vs "
                f"{trained.evader_slots} in its slots), not a scenario whose observation "
                f"holds {self.config.pursuer_slots} vs {self.config.evader_slots}"
            )
        self.name = Path(onnx_path).stem
        self.manifest = data
        self._session = self.session(onnx_path)

    @staticmethod
    def session(onnx_path: str | Path):
        import onnxruntime

        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = 1
        return onnxruntime.InferenceSession(
            str(onnx_path), options, providers=["CPUExecutionProvider"]
        )

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check(obs)
        return self._session.run([OUTPUTS[0]], {INPUT: obs})[0]
