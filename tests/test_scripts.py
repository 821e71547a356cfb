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
