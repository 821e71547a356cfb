"""Policies by name, for command lines and configs."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from hola_ray.env.config import PursuitConfig
from hola_ray.policies.apf import APFA
from hola_ray.policies.base import Policy
from hola_ray.policies.greedy import Greedy
from hola_ray.policies.vicsek import Vicsek

_FACTORIES: dict[str, Callable[[PursuitConfig], Policy]] = {
    "greedy": Greedy,
    "vicsek": Vicsek,
    **{f"apf-a-{k}": (lambda cfg, k=k: APFA(cfg, pair=k)) for k in range(24)},
}


def policy_names() -> list[str]:
    """Names `make_policy` accepts."""
    return list(_FACTORIES)


def make_policy(name: str, config: PursuitConfig) -> Policy:
    """The policy called `name` (case-insensitive) for this scenario."""
    key = name.lower()
    if key not in _FACTORIES:
        raise ValueError(f"unknown policy {name!r}; known: {', '.join(policy_names())}")
    return _FACTORIES[key](config)


def policy_file(path: str | Path) -> Path:
    """A run directory → its final learner (`learner.pt`); a file → itself."""
    path = Path(path)
    return path / "learner.pt" if path.is_dir() else path


def trained_scenario(path: str | Path) -> dict | None:
    """The scenario a run directory's learner or an export file was trained in, when its
    export says (`PursuitConfig.to_dict()`); None for a name or an older export."""
    import torch

    file = policy_file(Path(path))
    if not file.is_file():
        return None
    return torch.load(file, map_location="cpu", weights_only=True).get("scenario")


def load_policy(path: str | Path, config: PursuitConfig, name: str | None = None) -> Policy:
    """A learned policy from a run directory or an export file: an `MLPPolicy` export or a
    D3QN-G export, told apart by the export's format tag."""
    import torch

    from hola_ray.policies.d3qn import D3QNG
    from hola_ray.policies.d3qn import FORMAT as D3QN_FORMAT
    from hola_ray.policies.learned import MLPPolicy

    path = Path(path)
    file = policy_file(path)
    if not file.is_file():
        raise ValueError(f"{path}: neither a run directory with learner.pt nor a policy file")
    name = name or (path.name if path.is_dir() else path.stem)
    export = torch.load(file, map_location="cpu", weights_only=True)
    if export.get("format") == D3QN_FORMAT:
        return D3QNG(config, export, name=name)
    return MLPPolicy(config, export, name=name)
