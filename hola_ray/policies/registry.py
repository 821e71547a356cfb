"""Policies by name, for command lines and configs."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from hola_ray.env.config import PursuitConfig
from hola_ray.homes import GENERATION_EXPORT, GENERATION_STATE
from hola_ray.policies.apf import APFA
from hola_ray.policies.base import Policy
from hola_ray.policies.greedy import Greedy
from hola_ray.policies.hold import HoldHeading
from hola_ray.policies.vicsek import Vicsek

_FACTORIES: dict[str, Callable[[PursuitConfig], Policy]] = {
    "greedy": Greedy,
    "vicsek": Vicsek,
    "hold": HoldHeading,
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
    """A run directory → its final learner (`learner.pt`); a generation folder
    (`RUN/generations/gen_0012`) → that generation's learner export (the same name); a file
    → itself."""
    path = Path(path)
    return path / GENERATION_EXPORT if path.is_dir() else path


def load_export(path: str | Path) -> dict:
    """The plain-torch export of a run directory's learner, of a generation's learner or of
    an export file."""
    import torch

    path = Path(path)
    file = policy_file(path)
    if not file.is_file():
        older = (path / GENERATION_STATE).is_file()
        raise ValueError(
            f"{path}: a generation folder written before generations kept their export "
            f"({GENERATION_EXPORT}); play the run's learner.pt or best.pt instead"
            if older
            else f"{path}: neither a run directory with learner.pt, a generation folder "
            f"with {GENERATION_EXPORT}, nor a policy file"
        )
    try:
        export = torch.load(file, map_location="cpu", weights_only=True)
    except Exception as err:  # noqa: BLE001 - torch raises many kinds for a bad file
        first = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise ValueError(
            f"{file}: not a torch export ({type(err).__name__}: {first[:120]})"
        ) from err
    if not isinstance(export, dict):
        raise ValueError(f"{file}: not a policy export (a {type(export).__name__})")
    return export


def trained_scenario(path: str | Path) -> dict | None:
    """The scenario a run directory's learner or an export file was trained in, when its
    export or its manifest says (`PursuitConfig.to_dict()`); None for a name or an older
    export that no manifest lists."""
    from hola_ray.policies.learned import manifest_scenario

    try:
        return load_export(path).get("scenario") or manifest_scenario(policy_file(path))
    except ValueError:
        return None


def load_policy(path: str | Path, config: PursuitConfig, name: str | None = None) -> Policy:
    """A learned policy from a run directory or an export file: an `MLPPolicy` export or a
    D3QN-G export, told apart by the export's format tag."""

    from hola_ray.policies.d3qn import D3QNG
    from hola_ray.policies.d3qn import FORMAT as D3QN_FORMAT
    from hola_ray.policies.learned import MLPPolicy

    path = Path(path)
    export = load_export(path)
    if name is None and path.is_dir() and path.parent.name == "generations":
        name = f"{path.parent.parent.name}-{path.name}"  # run-gen_0012
    name = name or (path.name if path.is_dir() else path.stem)
    if export.get("format") == D3QN_FORMAT:
        return D3QNG(config, export, name=name)
    return MLPPolicy(config, export, name=name)
