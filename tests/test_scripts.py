"""The commands in `[project.scripts]`: each names a callable of a module that also runs as
`python -m`, and one of them, installed, answers --help."""

from __future__ import annotations

import importlib
import shutil
import subprocess
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_each_script_names_a_callable_of_a_python_m_module(name):
    module, _, attr = SCRIPTS[name].partition(":")
    assert callable(getattr(importlib.import_module(module), attr))
    source = (ROOT / (module.replace(".", "/") + ".py")).read_text()
    assert 'if __name__ == "__main__":' in source  # the same command by `python -m`


def test_the_core_commands_are_scripts():
    assert {"hola-run", "hola-experiment", "hola-eval", "hola-status"} <= set(SCRIPTS)


def test_an_installed_script_runs():
    exe = shutil.which("hola-status") or shutil.which(str(ROOT / ".venv/bin/hola-status"))
    if exe is None:
        pytest.skip("the project is not installed with its scripts in this environment")
    out = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "run_dir" in out.stdout


def test_python_m_hola_ray_names_every_command_and_runs_each():
    """`python -m hola_ray` lists the commands; `python -m hola_ray COMMAND` is the command
    (its --help); an unknown command is one line and exit code 2."""
    import sys

    from hola_ray.commands import COMMANDS

    def run(*args):
        cmd = [sys.executable, "-m", "hola_ray", *args]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)

    listed = run()
    assert listed.returncode == 2 and all(name in listed.stdout for name in COMMANDS)
    assert "experiment" in listed.stdout
    for name in COMMANDS:  # every one is a module of hola_ray.commands with a script
        assert callable(importlib.import_module(f"hola_ray.commands.{name}").script)
    status = run("status", "--help")
    assert status.returncode == 0 and "python -m hola_ray status" in status.stdout
    unknown = run("statuss")
    assert unknown.returncode == 2 and "unknown command 'statuss'" in unknown.stderr
