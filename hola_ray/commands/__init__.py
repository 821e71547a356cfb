"""The command lines, one module each: `python -m hola_ray COMMAND …` (or its `hola-*`
script from pyproject.toml). `python -m hola_ray.run` stays the main job's own command."""

COMMANDS = {
    "run": "train one run (the main job)",
    "evaluate": "zero-shot evaluation against the teammate pools",
    "status": "a run's progress, its figure and its decisions",
    "replay": "one episode drawn, or animated",
    "export": "a learner as ONNX with its manifest",
    "fly": "a learner flown as Crazyflies",
    "pools": "build and check the evaluation pools",
    "populations": "build and check the shipped populations",
}
"""command → what it does; each is `hola_ray.commands.<command>`, whose `main(argv)` runs it"""
