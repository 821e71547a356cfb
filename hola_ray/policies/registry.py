"""Policies by name, for command lines and configs."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from hola_ray.config.layout import ObsLayout
from hola_ray.config.scenario import PursuitConfig
from hola_ray.homes import GENERATION_EXPORT, GENERATION_STATE
from hola_ray.policies.apf import APFA
from hola_ray.policies.base import Policy
from hola_ray.policies.greedy import Greedy
from hola_ray.policies.hold import HoldHeading
from hola_ray.policies.surround import SURROUND_MEMBERS, Surround
from hola_ray.policies.vicsek import Vicsek

_FACTORIES: dict[str, Callable[[PursuitConfig], Policy]] = {
    "greedy": Greedy,
    "vicsek": Vicsek,
    "hold": HoldHeading,
    **{f"apf-a-{k}": (lambda cfg, k=k: APFA(cfg, pair=k)) for k in range(24)},
    **{k: (lambda cfg, p=p: Surround(cfg, p)) for k, p in SURROUND_MEMBERS.items()},
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


def trained_scenario(path: str | Path) -> PursuitConfig | None:
    """The scenario a learner was trained in: the one answer `evaluate`, `replay`, `fly`
    and the experiment's evaluation ask for. From, first to last: a run directory's
    config.yaml, an ONNX file's manifest, the export's own record, the pool or population
    manifest beside the file, and, for an older export no manifest lists, the paper's
    arena with as many evaders as its input size holds. None for a D3QN-G export, which
    reads the first evader only and plays any scenario. A path that is no learner raises
    `ValueError` in one line."""
    import yaml

    from hola_ray.policies.d3qn import FORMAT as D3QN_FORMAT
    from hola_ray.policies.learned import manifest_scenario

    path = Path(path)
    if not path.exists():
        raise ValueError(f"{path}: no such file or directory")
    if path.is_dir() and (path / "config.yaml").is_file():
        run = yaml.safe_load((path / "config.yaml").read_text()) or {}
        return PursuitConfig.from_dict(run.get("env") or {})
    if path.suffix == ".onnx":
        from hola_ray.policies.deploy import read_manifest

        return PursuitConfig.from_dict(read_manifest(path)["scenario"])
    export = load_export(path)
    if export.get("format") == D3QN_FORMAT:
        return None
    file = policy_file(path)
    if not isinstance(export.get("weights"), list | tuple) or not export["weights"]:
        raise ValueError(f"{file}: not a policy export (no weights)")
    scenario = export.get("scenario") or manifest_scenario(file)
    if scenario:
        return PursuitConfig.from_dict(scenario)
    inputs = export["weights"][0].shape[1] - len((export.get("features") or {}).get("indices", ()))
    evaders = ObsLayout.evaders_for(inputs, PursuitConfig().n_pursuers)
    if evaders is None:
        raise ValueError(f"{file}: an input of {inputs} fits no number of evaders")
    return PursuitConfig(n_evaders=evaders)


def played_scenario(path: str | Path) -> PursuitConfig | None:
    """The scenario a learner is evaluated in: the one it trained in (`trained_scenario`)
    with the default reward, so that every learner's returns are counted alike."""
    trained = trained_scenario(path)
    return None if trained is None else trained.played()


def load_fitted(
    path: str | Path,
    config: PursuitConfig,
    trained: PursuitConfig | None = None,
    name: str | None = None,
) -> Policy:
    """A learned policy (a run directory or an export file) playing `config`, whatever its
    team and slots (contract §6.2): built in the scenario it was trained in (`trained`,
    else the file's own: `played_scenario`) and fitted to `config`'s observation through
    the adapter (`fitted`). A D3QN-G export reads the first evader only: it is built in
    `config` with its own team's slots. The one rule the pools, the reference seats and
    the open-team grid's learners load learned policies by (flight fits an already loaded
    policy with `fitted`)."""
    from hola_ray.policies.adapter import fitted
    from hola_ray.policies.adapter import trained_scenario as observed_as
    from hola_ray.policies.d3qn import FORMAT as D3QN_FORMAT
    from hola_ray.policies.d3qn import state_pursuers

    export = load_export(Path(path))
    if export.get("format") == D3QN_FORMAT:
        trained = observed_as(config, state_pursuers(export), config.evader_slots)
    elif trained is None:
        trained = played_scenario(path)
    return fitted(config, load_policy(path, trained, name))


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
